"""Step strategies, chosen by name by the scene's ``solver.step`` as the contact solvers are
by ``solver.contact``: how the equations of one step are iterated.

- ``fixed_point`` (compute.stepping.newton): the Newton loop around a complete contact solve
  per iteration, with positive definite matrices; any scene.
- ``active_set`` (compute.stepping.active_set): a semismooth Newton on the step's coupled
  problem, the contact conditions linearised inside the iteration, with the exact (possibly
  indefinite) matrix; for one soft body alone with the walls, frictionless, its rotation held
  (its contact problem is one small dense block, solved directly at every iteration). A step it
  does not take is taken again by ``fixed_point``.
- ``auto``: ``active_set`` where it applies, ``fixed_point`` elsewhere (docs/ARCHITECTURE.md says
  why).

A strategy is a function ``(step, contacts, v_minus, solver, tol, max_iterations, misses_fail,
end_rows) -> (v, SolveReport, StepStats)`` over a GroupStep (compute.stepping.groups);
``end_rows`` the rows it makes again at the first iterate (compute.contact.end_of_step) or None.
"""

from __future__ import annotations

from compute.errors import SceneError
from compute.stepping import active_set, newton

STRATEGIES = {"fixed_point": newton.solve_step, "active_set": active_set.solve_step}


def for_scene(settings, scene_file, n_soft: int, n_moving_rigid: int, frictional: bool):
    """The strategy that a scene's ``[solver]`` ``settings`` name, for a scene (file
    ``scene_file``) with ``n_soft`` soft bodies, ``n_moving_rigid`` movable rigid disks and
    some friction (``frictional``); an explicit ``active_set`` where it does not apply raises
    SceneError naming the file and the key."""
    applies = bool(settings.hold_rotation and n_soft == 1 and n_moving_rigid == 0 and not frictional)
    name = settings.step
    if name == "auto":
        name = "active_set" if applies else "fixed_point"
    elif name == "active_set" and not applies:
        raise SceneError(scene_file, "solver.step",
                         '"fixed_point" or "auto" for this scene: "active_set" takes one soft body with '
                         "solver.hold_rotation = true, no friction and no movable rigid disk (this scene: "
                         f"{n_soft} soft bodies, hold_rotation = {str(settings.hold_rotation).lower()}, "
                         f"{'frictional' if frictional else 'frictionless'}, {n_moving_rigid} movable rigid disks)",
                         name)
    return STRATEGIES[name]


def for_model(settings, model):
    """The strategy of ``settings`` for a :class:`compute.model.Model`."""
    return for_scene(settings, model.scene.path / "scene.toml", len(model.soft_ids), model.moving_rigid,
                     bool(model.friction.any()))
