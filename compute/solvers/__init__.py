"""Contact solvers: each takes a :class:`compute.contact.problem.ContactProblem` and returns the
end-of-step velocities, with the impulses written into ``problem.impulse``.

The interface is one method, ``solve(problem) -> SolveReport`` (:mod:`compute.solvers.report`); a
solver knows nothing of body kinds. Chosen by the scene's ``solver.contact`` (:func:`for_scene`):

- ``"nlgs"``: :class:`~compute.solvers.nlgs.NLGS`, nonlinear Gauss–Seidel with the exact local 2D
  Signorini–Coulomb solution per contact;
- ``"block"``: :class:`~compute.solvers.block_gs.BlockGS`, the contacts of each soft body solved
  exactly together (semismooth Newton), Gauss–Seidel over bodies and single contacts;
- ``"nlgs_block"``: :meth:`compute.solvers.nlgs_then.NLGSThen.block`, NLGS until it stalls, then
  block Gauss–Seidel;
- ``"nlgs_ip"``: :meth:`compute.solvers.nlgs_then.NLGSThen.interior_point`, NLGS until it stalls
  or would miss its tolerance within its sweeps, then an interior point, then NLGS again;
- ``"interior_point"``: :class:`~compute.solvers.interior_point.InteriorPoint`, all contacts of
  the packing solved together (Mehrotra predictor–corrector on the problem's LCP form, sparse
  LU), a number of iterations that does not grow with the packing; ``nlgs_max_sweeps`` bounds
  its iterations too. It does not converge on jammed frictional rigid packings, and once per
  Newton iteration it costs more than warm-started Gauss–Seidel, so ``auto`` uses it only as
  ``nlgs_ip``'s fallback (benchmarks/results/contact_problems.md);
- ``"cone_point"``: :class:`~compute.solvers.cone_point.ConePoint`, De Saxcé's friction shift as
  a fixed point, each step a monotone LCP over the Coulomb cones solved by the same interior
  point: converges where ``interior_point`` stalls, on jammed frictional rigid packings;
  ``nlgs_max_sweeps`` bounds its interior-point iterations too;
- ``"mprgp"``: :class:`~compute.solvers.mprgp.MPRGP`, frictionless contact only (a scene with
  friction is refused): the problem as a bound-constrained quadratic program, solved by
  projected conjugate gradients on the whole packing, warm-started; ``nlgs_max_sweeps`` bounds
  its iterations;
- ``"auto"`` (default): ``mprgp`` for a packing without friction of more than
  ``AUTO_QP_BODIES`` movable bodies, rigid or soft; otherwise, without soft bodies, ``nlgs_ip`` up
  to ``AUTO_FALLBACK_BODIES`` movable rigid bodies and ``nlgs`` above (a block would be one
  contact: the same iteration, dearer); ``block`` for a scene whose only moving bodies are one
  soft body and the walls; ``nlgs_block`` for soft bodies among other bodies. Why: near jamming, frictional rigid packings pose contact
  problems on which NLGS needs tens of thousands of sweeps, so its solves end above tolerance at
  their sweep limit; with the interior-point fallback the rigid_jamming study's default runs end
  COMPLETE in less time, but the fallback's sparse factorisations grow faster than a sweep:
  on larger packings the run costs more than with NLGS, the more so the larger (it ends
  COMPLETE where NLGS does not, or leaves fewer steps above tolerance;
  benchmarks/results/contact_problems.md, "Rigid runs"). On one soft body the point
  Gauss–Seidel contracts slowly, the body's contacts being coupled through its compliance, while the block is one
  Newton solve. In soft mixtures the slow coupling is between bodies, through the contact
  network, where blocks take as many sweeps as points at a higher cost per sweep; but while a
  mixture compacts, ``nlgs`` can stall where ``block`` converges (:mod:`compute.solvers.nlgs_then`),
  hence ``nlgs_block``; ``nlgs_ip`` there is slower at the default tolerance (a cold interior
  point per fallback, at any Newton iteration) and pays off only at tight ones. Without
  friction the contact problem is a convex quadratic program, and ``mprgp``, conjugate gradients
  over the whole packing, needs far fewer iterations than NLGS needs sweeps, each a little dearer
  than a sweep: frictionless mixtures run markedly faster, and so do frictionless rigid
  packings (benchmarks/results/frictionless_relaxation.md). ``nlgs_block`` is kept for the
  smallest ones (up to ``AUTO_QP_BODIES``), where the gain is least, so that they run as they
  did: the 30-disk default's κ = 0.5 frictionless run equilibrates its second stage only by
  chance, and does not with ``mprgp``, nor with NLGS at a tighter tolerance. Figures:
  benchmarks/results/design_figures.md, benchmarks/results/contact_problems.md,
  benchmarks/results/frictionless_qp.md.

With ``solver.contact_screening`` > 0 the chosen solver is given only the contacts that can close
(:class:`~compute.solvers.screened.Screened`): those holding an impulse or approaching within
that fraction of the fastest free approach, and the ones left out that close at its solution,
round after round; the solution is the whole problem's.

All stop on the error of :mod:`compute.contact.residual` that the scene's
``solver.contact_error`` names (their ``measure``), with its optional penetration bound, and
report it.
"""

from __future__ import annotations

import numpy as np


MAX_INTERIOR_POINT_ITERATIONS = 200  # an interior point that needs more has stalled
AUTO_FALLBACK_BODIES = 500  # auto: rigid scenes up to this many movable bodies get nlgs_ip (module docstring)
AUTO_QP_BODIES = 100  # auto: frictionless packings above this many movable bodies get mprgp (module docstring)


def for_model(settings, model):
    """The contact solver of ``settings`` (a scene's ``[solver]``) for a :class:`compute.model.Model`."""
    return for_scene(settings, sum(len(g) for g in model.soft), int(np.count_nonzero(~model.rigid.fixed)),
                     model.diameter, frictionless=not np.any(model.friction > 0.0))


def for_scene(settings, n_soft: int, n_rigid: int, diameter: float = 1.0, frictionless: bool = False):
    """The contact solver of a scene's ``[solver]`` settings (module docstring), for a scene
    with ``n_soft`` soft bodies, ``n_rigid`` movable rigid disks and mean diameter ``diameter``
    (the unit of ``penetration_bound``), ``frictionless`` if no pair of materials has friction;
    with ``contact_screening`` > 0, solving on the contacts that can close
    (:class:`compute.solvers.screened.Screened`)."""
    solver = _chosen(settings, n_soft, n_rigid, diameter, frictionless)
    if settings.contact_screening > 0.0:
        from compute.solvers.screened import Screened

        return Screened(solver, settings.contact_screening)
    return solver


def _chosen(settings, n_soft: int, n_rigid: int, diameter: float, frictionless: bool):
    """The solver ``settings.contact`` names, or auto's choice (module docstring)."""
    from compute.solvers.block_gs import BlockGS
    from compute.solvers.cone_point import ConePoint
    from compute.solvers.interior_point import InteriorPoint
    from compute.solvers.mprgp import MPRGP
    from compute.solvers.nlgs import NLGS
    from compute.solvers.nlgs_then import NLGSThen
    from compute.contact.residual import Measure

    measure = Measure(settings.contact_error, settings.penetration_bound * diameter)
    tol, sweeps = settings.contact_tolerance, settings.nlgs_max_sweeps
    kind = settings.contact
    if kind == "auto":
        if frictionless and n_soft + n_rigid > AUTO_QP_BODIES:
            kind = "mprgp"
        elif n_soft == 0:
            kind = "nlgs_ip" if n_rigid <= AUTO_FALLBACK_BODIES else "nlgs"
        elif n_rigid == 0 and n_soft == 1:
            kind = "block"
        else:
            kind = "nlgs_block"
    if kind == "interior_point":
        return InteriorPoint(tol, min(sweeps, MAX_INTERIOR_POINT_ITERATIONS), measure)
    if kind == "mprgp":
        return MPRGP(tol, sweeps, measure)
    if kind == "cone_point":
        return ConePoint(tol, min(sweeps, MAX_INTERIOR_POINT_ITERATIONS), measure)
    if kind == "block":
        return BlockGS(tol, sweeps, measure)
    if kind == "nlgs_block":
        return NLGSThen.block(tol, sweeps, settings.relaxation, measure)
    if kind == "nlgs_ip":
        return NLGSThen.interior_point(tol, sweeps, settings.relaxation, measure, soft=n_soft > 0)
    return NLGS(tol, sweeps, settings.relaxation, measure=measure)
