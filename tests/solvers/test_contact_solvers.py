"""The contact solvers against an independent answer: a textbook Lemke pivoting solver of the
2D frictional problem written as an LCP (tests/solvers/lemke.py), on random small problems;
and the natural-map error (compute.contact.residual) against the oracle's exact solutions."""

import numpy as np
import pytest

from compute.solvers.block_gs import BlockGS
from compute.solvers.cone_point import ConePoint
from compute.solvers.interior_point import InteriorPoint
from compute.solvers.mprgp import MPRGP
from compute.solvers.nlgs import NLGS
from compute.solvers.nlgs_then import NLGSThen
from compute.solvers.screened import Screened
from compute.contact.residual import Measure, natural_map_error
from tests.solvers.lemke import frictional_lcp, lemke, solve_contact
from tests.solvers.problems import bodies_problem, dense_form, random_problem

def solver_of(name, tol, measure=None):
    """A fresh solver of kind ``name`` stopping at ``tol`` in ``measure`` (default: impulse)."""
    m = measure or Measure()
    return {"nlgs": lambda: NLGS(tol, 200_000, measure=m), "block": lambda: BlockGS(tol, 20_000, m),
            "nlgs_block": lambda: NLGSThen.block(tol, 200_000, measure=m),
            "nlgs_ip": lambda: NLGSThen.interior_point(tol, 200_000, measure=m),
            "interior_point": lambda: InteriorPoint(tol, 200, m), "cone_point": lambda: ConePoint(tol, 400, m)}[name]()


SOLVERS = {name: solver_of(name, 1e-13) for name in ("nlgs", "block", "nlgs_block", "nlgs_ip", "interior_point",
                                                     "cone_point")}
KINDS = ("rigid", "soft", "mixed")


def error_of(p, r):
    """Natural-map error of impulses r (nc, 2) of problem p."""
    C, H, _, _ = dense_form(p)
    v = p.free_velocity() + C @ (H @ r.ravel())
    return natural_map_error(p.dof, p.hn, p.ht, p.W, p.gap_term, p.mu, np.ascontiguousarray(r), v)


def test_lemke_solves_a_known_lcp():
    """A 2x2 LCP solved by hand: A = [[2, 1], [1, 2]], q = (-5, -6): both active, z = (4/3, 7/3)."""
    z = lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))
    np.testing.assert_allclose(z, [4 / 3, 7 / 3], rtol=1e-14)


@pytest.mark.parametrize("kind", KINDS + ("rank_deficient",))
@pytest.mark.parametrize("seed", range(8))
def test_oracle_solutions_satisfy_the_law(kind, seed):
    """The LCP's solution is a solution of the contact law: complementarity of the LCP, and a
    natural-map error at rounding level; a perturbed solution has a clearly positive error."""
    p = random_problem(np.random.default_rng(seed), kind, 6)
    _, _, W, b = dense_form(p)
    A, q = frictional_lcp(W, b, p.mu)
    z = lemke(A, q)
    w = A @ z + q
    assert z.min() >= 0 and w.min() > -1e-10 and abs(z @ w) < 1e-10
    r = solve_contact(W, b, p.mu)
    assert error_of(p, r) < 1e-12
    if np.abs(r).max() > 0:
        assert error_of(p, r * 1.01 + 1e-3) > 1e-4


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("kind", KINDS)
def test_solver_matches_lemke(solver, kind):
    """On 30 random problems of 8 contacts: every solve that reports convergence agrees with the
    oracle within 1e-10 and reports the error it reached; a solve that does not converge says so
    (point Gauss–Seidel on a frictional problem is not guaranteed to converge: about 1 in 100 of
    these problems, where W is ill-conditioned); at most 2 of 30 do not. A frictional problem
    may have several solutions (seen once in 100 soft problems, cond(W) = 1600): a converged
    answer that differs from the oracle's must then have a zero error recomputed here."""
    missed = 0
    for seed in range(30):
        p = random_problem(np.random.default_rng(100 + seed), kind, 8)
        _, _, W, b = dense_form(p)
        expected = solve_contact(W, b, p.mu)
        report = SOLVERS[solver].solve(p)
        assert report.residual == pytest.approx(error_of(p, p.impulse), rel=1e-6, abs=1e-12)  # v updated in place vs recomputed
        if report.residual > 1e-13:
            missed += 1
            continue
        scale = max(np.abs(expected).max(), 1.0)
        if np.abs(p.impulse - expected).max() > 1e-10 * scale:
            assert error_of(p, p.impulse) < 1e-12 and error_of(p, expected) < 1e-12, "a wrong answer"
    assert missed <= 2


@pytest.mark.parametrize("solver", [name for name in SOLVERS if name != "cone_point"])
@pytest.mark.parametrize("seed", range(10))
def test_solver_matches_lemke_on_rank_deficient_problems(solver, seed):
    """W singular (8 contacts on 3 dofs): impulses are not unique, the contact velocities and the
    error are compared."""
    p = random_problem(np.random.default_rng(200 + seed), "rank_deficient", 8)
    C, H, W, b = dense_form(p)
    assert np.linalg.matrix_rank(W) < W.shape[0]
    expected = solve_contact(W, b, p.mu)
    report = SOLVERS[solver].solve(p)
    u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-8 * max(np.abs(u_ref).max(), 1.0))
    assert report.residual <= 1e-13


def test_cone_point_on_rank_deficient_problems():
    """cone_point on the rank-deficient problems: where it reports convergence the contact
    velocities are the oracle's; it converges on at least 7 of 10. (With s = 0 a cone LCP of
    these problems can have no solution: a self-stress inside the cones whose cost (q + s e_n)ᵀ r
    is negative, from the overlapping gaps; the proximal term keeps the impulses finite, so a miss
    shows as an error, not as a relative error fooled by huge impulses.)"""
    converged = 0
    for seed in range(10):
        p = random_problem(np.random.default_rng(200 + seed), "rank_deficient", 8)
        _, _, W, b = dense_form(p)
        expected = solve_contact(W, b, p.mu)
        report = SOLVERS["cone_point"].solve(p)
        assert report.residual == pytest.approx(error_of(p, p.impulse), rel=1e-6, abs=1e-12)
        if report.residual > 1e-13:
            continue
        converged += 1
        u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-8 * max(np.abs(u_ref).max(), 1.0))
    assert converged >= 7


def cone_lcp_dense(p, s, centre):
    """(M, b, A) of the cone LCP of problem p (compute.solvers.cone_point) for shift s (nc,) and
    proximal centre (nc, 2), from the dense form: r = A z, M = Aᵀ (W + ε P) A, b = Aᵀ (q + s e_n -
    ε P r̄), A's columns √ρ_c (1, ±μ_c) (one, (1, 0), without friction)."""
    from compute.solvers.cone_point import PROXIMAL

    _, _, W, q = dense_form(p)
    nc = len(p)
    rho = 1.0 / np.diag(W)[0::2]
    columns = []
    for c in range(nc):
        for t in ((p.mu[c], -p.mu[c]) if p.mu[c] > 0 else (0.0,)):
            a = np.zeros(2 * nc)
            a[2 * c], a[2 * c + 1] = np.sqrt(rho[c]), np.sqrt(rho[c]) * t
            columns.append(a)
    A = np.array(columns).T
    P = np.diag(np.repeat(1.0 / rho, 2))
    shifted = q.copy()
    shifted[0::2] += s
    return A.T @ (W + PROXIMAL * P) @ A, A.T @ (shifted - PROXIMAL * P @ centre.ravel()), A


@pytest.mark.parametrize("kind", KINDS)
def test_cone_lcp_interior_point_is_exact(kind):
    """The monotone cone LCP of one outer step, solved by the interior point to its own error
    1e-14, against Lemke on the same LCP built independently from the dense form: the same
    impulses (M is positive definite here, the solution unique)."""
    from compute.contact.delassus import Delassus
    from compute.solvers.cone_point import ConeLCP, PROXIMAL
    from compute.solvers.interior_point import local_free_velocity

    for seed in range(5):
        rng = np.random.default_rng(300 + seed)
        p = random_problem(rng, kind, 8)
        s = rng.uniform(0.0, 0.5, len(p)) * (p.mu > 0)
        centre = rng.normal(size=(len(p), 2)) * 0.1
        M, b, A = cone_lcp_dense(p, s, centre)
        expected = (A @ lemke(M, b)).reshape(-1, 2)
        W = Delassus.of_problem(p)
        q = local_free_velocity(p)
        lcp = ConeLCP(W, q, p.mu, PROXIMAL)
        np.testing.assert_allclose(lcp.M.toarray(), M, atol=1e-13 * np.abs(M).max())
        codes = Measure().codes(p, 1e-14)

        def stop(z, w, last):
            r = lcp.impulses(z)
            return last or lcp.shifted_error(codes, W.times(r) + q, r, s, centre) <= 1e-14

        z, _, iterations = lcp.solve(s, centre, stop, 100)
        assert iterations < 100
        np.testing.assert_allclose(lcp.impulses(z), expected, rtol=0, atol=1e-10 * max(np.abs(expected).max(), 1.0))


def test_shift_fixed_point_is_a_coulomb_solution():
    """Without the Levenberg–Marquardt polish, the fixed point of s alone reaches a natural-map
    error at rounding level on a rigid problem where s <- μ |u_t| contracts, and that is the
    oracle's solution; the shifts then equal μ |u_t|."""
    from compute.solvers.cone_point import ConePoint

    p = random_problem(np.random.default_rng(100), "rigid", 8)  # 101 stalls at 1.8e-9 without the polish
    _, _, W, b = dense_form(p)
    expected = solve_contact(W, b, p.mu)
    report = ConePoint(1e-13, 1000, outer=100, polish=0).solve(p)
    assert report.residual <= 1e-13 and error_of(p, p.impulse) <= 1e-13
    np.testing.assert_allclose(p.impulse, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    u = W @ p.impulse.ravel() + b
    closed = p.impulse[:, 0] > 1e-8 * p.impulse[:, 0].max()  # the interior point leaves open contacts at ~1e-17
    np.testing.assert_allclose(u[0::2][closed], 0.0, atol=1e-10 * np.abs(b).max())  # ũ_n + μ|u_t| ⊥ r with u_n = 0


def _nearest_on_cone(x, mu):
    """Projection on K = {|t| <= mu n} by brute force: the nearest of 0, x (if in K) and the
    nearest points of the two edge rays."""
    candidates = [np.zeros(2)] + ([x] if x[0] >= 0 and abs(x[1]) <= mu * x[0] else [])
    for s in (1.0, -1.0):
        d = np.array([1.0, s * mu]) / np.hypot(1.0, mu)
        candidates.append(max(x @ d, 0.0) * d)
    return min(candidates, key=lambda c: np.linalg.norm(x - c))


@pytest.mark.parametrize("mu", [0.0, 0.3, 1.0])
def test_cone_projection_is_the_nearest_point(mu):
    """Including the frictionless cone (a half-line) and points on the axes (a node–wall contact
    has a zero tangent row, so x_t = 0 exactly)."""
    from compute.contact.residual import project_cone

    rng = np.random.default_rng(7)
    points = [np.array(p, float) for p in ([-1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, -1.0], [0.0, 0.0])]
    points += list(rng.normal(size=(200, 2)))
    for x in points:
        np.testing.assert_allclose(project_cone(x[0], x[1], mu), _nearest_on_cone(x, mu), atol=1e-15)


def test_open_frictionless_contact_without_tangent_row_has_no_error():
    """r = 0 on an open contact whose tangent row is zero (node–wall) is the solution: error 0."""
    from compute.contact.residual import local_error

    assert local_error(5.0, 0.2, 0.0, 0.0, 0.0, 0.0) == (0.0, 0.0)
    assert local_error(5.0, -0.2, 0.0, 0.0, 0.0, 0.0)[0] == pytest.approx(-0.04)  # closing, r = 0: -ρ ũ_n


@pytest.mark.parametrize("kind, seed", [("soft", 25), ("soft", 194), ("mixed", 159), ("mixed", 190), ("mixed", 214)])
def test_block_fallback_solves_problems_where_point_gauss_seidel_stalls(kind, seed):
    """Random frictional problems (found by search) on which point Gauss–Seidel does not converge
    in 20 000 sweeps: NLGS with the block fallback stops its sweeps on the stall and reaches the
    oracle's solution."""
    import copy

    p = random_problem(np.random.default_rng(1000 + seed), kind, 8)
    q = copy.deepcopy(p)
    assert NLGS(1e-12, 20_000).solve(q).residual > 1e-6
    _, _, W, b = dense_form(p)
    expected = solve_contact(W, b, p.mu)
    report = NLGSThen.block(1e-12, 20_000).solve(p)
    assert report.iterations < 1000 and report.residual <= 1e-12
    u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-9 * max(np.abs(u_ref).max(), 1.0))


def test_auto_choice():
    """nlgs_ip (cone fixed point as its rigid fallback) for a small rigid packing, nlgs for a
    large one, block for one soft body alone in its walls, nlgs_block for soft bodies among others,
    mprgp for more than AUTO_QP_BODIES bodies without friction, rigid or soft (compute.solvers docstring)."""
    from types import SimpleNamespace

    from compute.solvers import for_scene

    settings = SimpleNamespace(contact="auto", contact_tolerance=1e-6, nlgs_max_sweeps=10, relaxation=1.0,
                               contact_error="impulse", penetration_bound=0.0, contact_screening=0.0)
    assert isinstance(for_scene(settings, 1, 0), BlockGS)
    assert isinstance(for_scene(settings, 1, 3).fallbacks[0], BlockGS) and isinstance(for_scene(settings, 72, 72).fallbacks[0], BlockGS)
    assert isinstance(for_scene(settings, 2, 0).fallbacks[0], BlockGS)
    assert isinstance(for_scene(settings, 0, 100).fallbacks[1], ConePoint)
    assert isinstance(for_scene(settings, 0, 1500), NLGS)
    assert isinstance(for_scene(settings, 0, 1500, frictionless=True), MPRGP)  # a large frictionless rigid packing
    assert isinstance(for_scene(settings, 0, 100, frictionless=True).fallbacks[1], ConePoint)
    assert isinstance(for_scene(SimpleNamespace(**{**vars(settings), "contact": "block"}), 72, 72), BlockGS)
    assert isinstance(for_scene(SimpleNamespace(**{**vars(settings), "contact": "mprgp"}), 72, 72), MPRGP)
    assert isinstance(for_scene(settings, 300, 1200, frictionless=True), MPRGP)  # a large frictionless mixture
    assert isinstance(for_scene(settings, 300, 1200).fallbacks[0], BlockGS)  # with friction
    assert isinstance(for_scene(settings, 72, 72, frictionless=True), MPRGP)
    assert isinstance(for_scene(settings, 10, 20, frictionless=True).fallbacks[0], BlockGS)  # a small one
    assert isinstance(for_scene(settings, 1, 0, frictionless=True), BlockGS)  # one soft body alone
    screened = for_scene(SimpleNamespace(**{**vars(settings), "contact_screening": 0.1}), 300, 1200, frictionless=True)
    assert isinstance(screened, Screened) and isinstance(screened.inner, MPRGP) and screened.margin == 0.1


def test_block_solver_with_redundant_contacts():
    """Two identical contacts in one soft block (the block's Jacobian is singular): the solver
    takes a least-squares Newton step instead of failing, and the answer satisfies the law."""
    p = random_problem(np.random.default_rng(5), "soft", 6)
    p.dof[1], p.hn[1], p.ht[1], p.gap_term[1], p.mu[1] = p.dof[0], p.hn[0], p.ht[0], p.gap_term[0], p.mu[0]
    p.gap_term[0] = p.gap_term[1] = -5.0  # both closing
    from compute.contact.compliance import delassus_blocks

    delassus_blocks(p.dof, p.hn, p.ht, *p.compliance.arrays(), p.W)
    report = BlockGS(1e-10, 1000).solve(p)
    assert report.residual <= 1e-10 and error_of(p, p.impulse) <= 1e-9
    assert p.impulse[0, 0] + p.impulse[1, 0] > 0


@pytest.mark.parametrize("kind", KINDS + ("rank_deficient",))
def test_whole_packing_delassus_is_the_dense_product(kind):
    """compute.contact.delassus assembles W = Hᵀ C H group by group; the dense product of the
    test's own H and C is the independent answer."""
    from compute.contact.delassus import Delassus

    for seed in range(5):
        p = random_problem(np.random.default_rng(300 + seed), kind, 10)
        _, _, W, _ = dense_form(p)
        D = Delassus.of_problem(p)
        np.testing.assert_allclose(D.dense(), W, rtol=0, atol=1e-13 * np.abs(W).max())
        r = np.random.default_rng(seed).normal(size=(10, 2))
        np.testing.assert_allclose(D.times(r).ravel(), W @ r.ravel(), rtol=0, atol=1e-12 * np.abs(W).max())


def test_packed_triangle_product_is_the_dense_product():
    """packed_times (rows four at a time, the rest one by one) adds A x to y for a symmetric A
    given by its packed upper triangle: numpy's dense product is the independent answer, for
    every size up to 13 (every remainder of four, and sizes below four), on strided views as
    the solver passes them."""
    from compute.contact.delassus import packed_times

    rng = np.random.default_rng(11)
    for n in range(14):
        a = rng.normal(size=(n, n))
        a = a + a.T
        tri = a[np.triu_indices(n)]  # row by row: (0, 0), (0, 1), ..., (1, 1), ...
        x = rng.normal(size=2 * n)[::2]
        y0 = rng.normal(size=n)
        y = y0.copy()
        packed_times(tri, n, x, y)
        np.testing.assert_allclose(y, y0 + a @ x, rtol=0, atol=1e-13 * max(1.0, np.abs(a).sum()))


def test_applied_impulses_are_the_dense_compliance_product():
    """apply_impulses adds M̂⁻¹ H r to v (a block's columns with an impulse four at a time, the
    rest one by one): the dense C H r of the test's own C and H is the independent answer, with
    impulses on some contacts only (blocks with 0 to all of their columns touched)."""
    from compute.solvers.nlgs import apply_impulses

    for seed in range(5):
        rng = np.random.default_rng(500 + seed)
        p = bodies_problem(rng, 30)
        C, H, _, _ = dense_form(p)
        r = rng.uniform(0.0, 1.0, (len(p), 2)) * (rng.random((len(p), 1)) < 0.6)
        v0 = rng.normal(size=len(p.compliance))
        v = v0.copy()
        apply_impulses(p.dof, p.hn, p.ht, r, v, *p.compliance.arrays())
        np.testing.assert_allclose(v, v0 + C @ H @ r.ravel(), rtol=0, atol=1e-13 * np.abs(C @ H).sum())


def test_velocity_error_is_the_velocity_of_the_wrong_impulse():
    """One frictionless rigid contact (W_nn = 2) closing at ũ_n = -1 without impulse: with the
    exact r = 1/2 the error is 0; with r = 1/4 (half of it) the contact still closes at -1/2, a
    velocity error of 1/2 against the velocity 1/2 that r = 1/4 makes: 1."""
    from compute.contact.compliance import Compliance
    from compute.contact.problem import ContactProblem

    comp = Compliance.build(2, [(np.arange(2), np.array([1.0, 1.0]))])
    dof = np.array([[0, 1, -1, -1, -1, -1, -1, -1]])
    hn = np.array([[-1.0, 1.0, 0, 0, 0, 0, 0, 0]])
    p = ContactProblem.of_rows(dof, hn, np.zeros_like(hn), comp, np.array([0.5, -0.5]), np.zeros(1), np.zeros(1),
                               np.zeros((1, 2)))
    assert p.W[0, 0, 0] == pytest.approx(2.0)
    for rn, expected in ((0.5, 0.0), (0.25, 1.0)):
        p.impulse[0, 0] = rn
        v = p.v_free + comp.diagonal * (hn[0, :2] * rn)
        assert p.velocity_error(v) == pytest.approx((expected, expected))


def velocity_errors_by_hand(p, r):
    """(packing, worst-contact) velocity errors of impulses r (nc, 2), and the largest predicted
    overlap h θ max(-ũ_n), from the dense form: u = W r + b, the Coulomb cone projection written
    out, e_c = W_nn f_c, w = W r (compute.contact.residual's module docstring)."""
    _, _, W, b = dense_form(p)
    w = (W @ r.ravel()).reshape(-1, 2)
    u = w + b.reshape(-1, 2)
    e = np.zeros_like(u)
    for c in range(len(p)):
        wnn, mu = W[2 * c, 2 * c], p.mu[c]
        x = wnn * r[c] - np.array([u[c, 0] + mu * abs(u[c, 1]), u[c, 1]])  # W_nn (r - ρ ū)
        if x[0] >= 0 and abs(x[1]) <= mu * x[0]:
            proj = x
        elif mu * abs(x[1]) <= -x[0]:
            proj = np.zeros(2)
        else:
            a = (x[0] + mu * abs(x[1])) / (1 + mu * mu)
            proj = np.array([a, np.sign(x[1]) * mu * a])
        e[c] = wnn * r[c] - proj
    e_c, w_c = np.hypot(e[:, 0], e[:, 1]), np.hypot(w[:, 0], w[:, 1])
    packing = np.linalg.norm(e_c) / np.linalg.norm(w_c) if e_c.max() > 0 else 0.0
    worst = e_c.max() / w_c.max() if e_c.max() > 0 else 0.0
    return packing, worst, p.h_theta * max(0.0, -u[:, 0].min())


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("kind", ("soft", "mixed"))
def test_solvers_stop_on_the_velocity_measures(solver, kind):
    """With ``velocity`` or ``velocity_max`` a solve that reports convergence holds that error,
    recomputed by hand from the dense form, and reports it (within rounding)."""
    for seed in range(10):
        base = random_problem(np.random.default_rng(700 + seed), kind, 8)
        for measure, which in (("velocity", 0), ("velocity_max", 1)):
            p = copy_problem(base)
            s = solver_of(solver, 1e-9, Measure(measure))
            report = s.solve(p)
            if report.residual > 1e-9:  # a Gauss–Seidel miss (test_solver_matches_lemke)
                continue
            by_hand = velocity_errors_by_hand(p, p.impulse)[which]
            assert by_hand <= 1.01e-9
            assert report.residual == pytest.approx(by_hand, rel=1e-6, abs=1e-11)


def test_penetration_bound_holds_the_predicted_overlap():
    """A loose tolerance with a penetration bound δ: the solve goes on until no contact's
    predicted end-of-step overlap h θ (-ũ_n) exceeds δ, recomputed from the dense form; without
    the bound the same loose solve leaves a larger overlap."""
    for seed in range(5):
        base = random_problem(np.random.default_rng(900 + seed), "mixed", 8)
        base.h_theta = 0.5
        base.gap_term[:] = -np.abs(base.gap_term) - 1.0  # every contact closing
        loose = copy_problem(base)
        NLGS(1e-1, 100_000).solve(loose)
        _, _, loose_overlap = velocity_errors_by_hand(loose, loose.impulse)
        assert loose_overlap > 0.0
        delta = 1e-3 * loose_overlap
        for solver in ("nlgs", "interior_point"):
            p = copy_problem(base)
            report = solver_of(solver, 1e-1, Measure("impulse", delta)).solve(p)
            assert report.residual <= 1e-1
            assert velocity_errors_by_hand(p, p.impulse)[2] <= delta * (1 + 1e-9)


def copy_problem(p):
    import copy

    return copy.deepcopy(p)


def chain_problem(n: int = 60, blocks: bool = False):
    """n unit masses in a row, all moving towards a fixed wall and stopped by it (frictionless):
    Gauss–Seidel carries the load one contact per sweep, so it needs of the order of n² sweeps,
    while W (tridiagonal, positive definite) is easy for a global method. With ``blocks`` each
    mass is a dense compliance block of its own (a body): block Gauss–Seidel's blocks are then
    the contacts one by one (the first two together), and it carries the load as slowly."""
    from compute.contact.compliance import Compliance
    from compute.contact.problem import ContactProblem

    if blocks:
        comp = Compliance.build(n, dense=[(np.arange(n + 1), np.arange(n), np.ones(n))])
    else:
        comp = Compliance.build(n, [(np.arange(n), np.ones(n))])
    m = 8
    dof = np.full((n, m), -1)
    hn = np.zeros((n, m))
    dof[0, 0], hn[0, 0] = 0, 1.0  # the wall: u_n = v_0
    for c in range(1, n):  # between c - 1 and c: u_n = v_c - v_{c-1}
        dof[c, :2], hn[c, :2] = (c - 1, c), (-1.0, 1.0)
    v_free = -1.0 - 0.5 * np.sin(np.arange(n))
    return ContactProblem.of_rows(dof, hn, np.zeros_like(hn), comp, v_free, np.zeros(n), np.zeros(n),
                                  np.zeros((n, 2)))


def test_nlgs_hands_a_slow_solve_to_the_interior_point():
    """On the chain, NLGS with a projected-sweeps limit stops early (above the tolerance, well
    before its budget); nlgs_ip then reaches the tolerance (error recomputed from the dense
    form) in far fewer iterations than NLGS alone needs."""
    from compute.solvers.nlgs_then import STALL_WINDOW

    PROJECTED_SWEEPS = 1000

    alone = chain_problem()
    plain = NLGS(1e-10, 1_000_000).solve(alone)
    assert plain.residual <= 1e-10 and plain.iterations > 20 * PROJECTED_SWEEPS
    early = NLGS(1e-10, 1_000_000, stall_window=STALL_WINDOW, projected_limit=PROJECTED_SWEEPS).solve(chain_problem())
    assert early.residual > 1e-10 and early.iterations < plain.iterations / 10
    p = chain_problem()
    report = NLGSThen.interior_point(1e-10, 5 * PROJECTED_SWEEPS).solve(p)  # a budget NLGS would miss
    assert report.residual <= 1e-10 and error_of(p, p.impulse) <= 1e-10
    assert report.iterations < plain.iterations / 10


def test_stall_test():
    """The stall test shared by NLGS and block Gauss–Seidel (compute.solvers.nlgs.stalled),
    checked every 10 sweeps, against the arithmetic: an error not below the last check's has
    stalled; one that fell from 1e-2 to 1e-3 in 10 sweeps reaches 1e-6 in 30 more (stalled only
    if fewer are allowed); from 1e-2 to 9e-3 it would need 864 more (ln(1e-6 / 9e-3) / ln 0.9 = 86.4
    windows)."""
    from compute.solvers.nlgs import stalled

    assert stalled(2e-3, 2e-3, 1e-6, 10, 0, 1000) and stalled(3e-3, 2e-3, 1e-6, 10, 0, 1000)
    assert not stalled(1e-3, np.inf, 1e-6, 10, 100, 1000)  # the first check: no contraction known yet
    assert not stalled(1e-3, 1e-2, 1e-6, 10, 0, 5)  # without a projected limit only oscillation stops
    assert not stalled(1e-3, 1e-2, 1e-6, 10, 31, 1000) and stalled(1e-3, 1e-2, 1e-6, 10, 29, 1000)
    assert stalled(1e-3, 1e-2, 1e-6, 10, 1000, 29)  # the budget left counts too
    assert not stalled(9e-3, 1e-2, 1e-6, 10, 870, 1000) and stalled(9e-3, 1e-2, 1e-6, 10, 860, 1000)


def test_block_gauss_seidel_stops_when_it_stalls():
    """On the chain of bodies block Gauss–Seidel contracts as slowly as point Gauss–Seidel
    (thousands of sweeps to 1e-10). With a stall window and a projected limit it stops early,
    above the tolerance, reporting the error of the impulses it leaves; without, it goes on to
    the tolerance."""
    plain = BlockGS(1e-10, 1_000_000).solve(chain_problem(blocks=True))
    assert plain.residual <= 1e-10 and plain.iterations > 2000
    p = chain_problem(blocks=True)
    early = BlockGS(1e-10, 1_000_000, stall_window=10, projected_limit=1000).solve(p)
    assert early.residual > 1e-10 and early.iterations < plain.iterations / 10
    assert early.residual == pytest.approx(error_of(p, p.impulse), rel=1e-6)


def test_nlgs_then_keeps_the_better_iterate():
    """A fallback that does worse than NLGS's iterate (an interior point allowed one iteration)
    is discarded: NLGSThen returns NLGS's impulses and error, and with ``resume`` NLGS goes on
    from them to the tolerance."""
    from compute.solvers.nlgs_then import STALL_WINDOW

    first = NLGS(1e-10, 1_000_000, stall_window=STALL_WINDOW, projected_limit=1000)
    p = chain_problem()
    kept = NLGSThen(first, (InteriorPoint(1e-10, 1),)).solve(p)
    q = chain_problem()
    alone = first.solve(q)
    assert kept.residual == pytest.approx(alone.residual) and np.array_equal(p.impulse, q.impulse)
    resumed = NLGSThen(first, (InteriorPoint(1e-10, 1),), resume=True).solve(chain_problem())
    assert resumed.residual <= 1e-10


def frictionless_problem(seed: int, kind: str):
    """A random problem of 8 contacts (tests/solvers/problems.py) with every μ set to 0."""
    p = random_problem(np.random.default_rng(seed), kind, 8)
    p.mu[:] = 0.0
    return p


@pytest.mark.parametrize("kind", KINDS + ("rank_deficient",))
def test_mprgp_matches_lemke_without_friction(kind):
    """MPRGP on 30 random frictionless problems (W singular for rank_deficient): each converges,
    reports the error it reached, has no tangential impulse, and gives the oracle's contact
    velocities (its impulses are unique only where W is regular)."""
    for seed in range(30):
        p = frictionless_problem(300 + seed, kind)
        _, _, W, b = dense_form(p)
        expected = solve_contact(W, b, p.mu)
        report = MPRGP(1e-13, 2000).solve(p)
        assert report.residual <= 1e-13
        assert report.residual == pytest.approx(error_of(p, p.impulse), rel=1e-6, abs=1e-12)
        assert not p.impulse[:, 1].any()
        u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
        np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-8 * max(np.abs(u_ref).max(), 1.0))


@pytest.mark.parametrize("measure", ("velocity", "velocity_max"))
def test_mprgp_stops_on_the_velocity_measures(measure):
    """A loose tolerance in a velocity measure: the error recomputed by hand from the dense form
    is within it and is the one reported."""
    which = {"velocity": 0, "velocity_max": 1}[measure]
    for seed in range(10):
        p = frictionless_problem(700 + seed, "mixed")
        report = MPRGP(1e-3, 2000, Measure(measure)).solve(p)
        by_hand = velocity_errors_by_hand(p, p.impulse)[which]
        assert report.residual <= 1e-3 and by_hand <= 1.01e-3
        assert report.residual == pytest.approx(by_hand, rel=1e-6, abs=1e-11)


def test_mprgp_holds_the_penetration_bound():
    """A loose tolerance with a penetration bound δ: no predicted overlap above δ (from the dense
    form), where the same loose solve without the bound leaves more (on at least 3 of 5)."""
    held = 0
    for seed in range(5):
        base = frictionless_problem(900 + seed, "mixed")
        base.h_theta = 0.5
        base.gap_term[:] = -np.abs(base.gap_term) - 1.0  # every contact closing
        loose = copy_problem(base)
        MPRGP(1e-1, 2000).solve(loose)
        overlap = velocity_errors_by_hand(loose, loose.impulse)[2]
        p = copy_problem(base)
        if overlap == 0.0:
            continue
        report = MPRGP(1e-1, 2000, Measure("impulse", 1e-3 * overlap)).solve(p)
        assert report.residual <= 1e-1
        assert velocity_errors_by_hand(p, p.impulse)[2] <= 1e-3 * overlap * (1 + 1e-9)
        held += 1
    assert held >= 3


def test_mprgp_carries_a_load_down_a_chain_in_few_iterations():
    """The chain of 60 masses against a wall: point Gauss–Seidel carries the load one contact per
    sweep (thousands of sweeps), conjugate gradients along the whole chain at once; MPRGP
    reaches the tolerance, recomputed from the dense form, in under a twentieth of NLGS's sweeps."""
    nlgs = NLGS(1e-10, 1_000_000).solve(chain_problem())
    p = chain_problem()
    report = MPRGP(1e-10, 100_000).solve(p)
    assert report.residual <= 1e-10 and error_of(p, p.impulse) <= 1e-10
    assert report.iterations < nlgs.iterations / 20


def fan_problem(k: int = 40, seed: int = 0):
    """k frictionless contacts on one unit mass, u_n,c = v + g_c (a pile of redundant rows): the
    unit-diagonal W_nn is the all-ones matrix, of norm k, so a projected-gradient step sized
    from the unit diagonal alone would be k / 2 times too long."""
    from compute.contact.compliance import Compliance
    from compute.contact.problem import ContactProblem

    rng = np.random.default_rng(seed)
    comp = Compliance.build(1, [(np.arange(1), np.ones(1))])
    dof = np.full((k, 8), -1)
    hn = np.zeros((k, 8))
    dof[:, 0], hn[:, 0] = 0, 1.0
    return ContactProblem.of_rows(dof, hn, np.zeros_like(hn), comp, np.array([-1.0]), rng.uniform(0.0, 0.5, k),
                                  np.zeros(k), np.zeros((k, 2)))


@pytest.mark.parametrize("warm", ("zero", "uniform", "one row"))
def test_mprgp_finds_its_step_on_a_stiff_pile_of_rows(warm):
    """The fan of 40 rows (‖W_nn‖ = 40 scaled): from cold, spread or concentrated warm starts
    MPRGP reaches 1e-12 with the oracle's contact velocities in no more iterations than rows:
    whatever way it sizes its expansion steps must hold on an operator whose norm is far from
    its unit diagonal."""
    p = fan_problem()
    p.impulse[:, 0] = {"zero": 0.0, "uniform": 0.05, "one row": np.eye(40)[7] * 3.0}[warm]
    _, _, W, b = dense_form(p)
    expected = solve_contact(W, b, p.mu)
    report = MPRGP(1e-12, 200).solve(p)
    assert report.residual <= 1e-12 and error_of(p, p.impulse) <= 1e-12
    u, u_ref = W @ p.impulse.ravel() + b, W @ expected.ravel() + b
    np.testing.assert_allclose(u, u_ref, rtol=0, atol=1e-9)
    assert report.iterations <= 40


def test_mprgp_keeps_a_warm_start_that_solves_the_problem():
    """Solved once, the same problem solved again from its impulses: no iteration, the same
    impulses to the last bit (a solution is left as it is, not moved within the tolerance)."""
    for seed in range(5):
        p = frictionless_problem(400 + seed, "mixed")
        MPRGP(1e-10, 2000).solve(p)
        kept = p.impulse.copy()
        again = MPRGP(1e-10, 2000).solve(p)
        assert again.iterations == 0 and again.residual <= 1e-10
        np.testing.assert_array_equal(p.impulse, kept)


def test_mprgp_refuses_friction():
    """A problem with a frictional contact is an error, not a frictionless answer to it."""
    p = random_problem(np.random.default_rng(5), "mixed", 8)
    assert p.mu.max() > 0
    with pytest.raises(ValueError, match="frictionless"):
        MPRGP(1e-8, 100).solve(p)


def test_mprgp_product_is_the_dense_normal_delassus():
    """MPRGP applies W_nn through the compliance (1x1 blocks, and soft bodies crowded with
    contacts) and through one dense W_G per other soft body (compute.contact.delassus.normal_groups),
    both kept as packed upper triangles, on problems where rows couple several bodies and rigid
    dofs: the product S W_nn S x, with the bodies' forms as chosen or all forced to one form,
    equals the dense H_nᵀ C H_n of the test's own H and C; and MPRGP's answer meets the
    complementarity conditions with that W."""
    from compute.contact.delassus import normal_groups
    from compute.solvers.mprgp import _times, _work

    for seed in range(5):
        p = bodies_problem(np.random.default_rng(400 + seed), 24)
        _, _, W, b = dense_form(p)
        Wnn = W[0::2, 0::2]
        c = p.compliance
        groups = normal_groups(p.dof, p.hn, c.block, c.start, c.offset, c.values)
        dense = groups[0]
        assert not dense[-1]  # the body without contact
        rng = np.random.default_rng(seed)
        s, x = rng.uniform(0.5, 2.0, len(p)), rng.normal(size=len(p))
        out = np.empty(len(p))
        touched = [bool(np.any(_dofs_of(p, c, g))) for g in range(dense.size)]
        assert dense.any() and any(t and not d for t, d in zip(touched, dense))  # both forms
        forms = {"as chosen": groups, "all compliance": _forced(np.zeros_like(dense), p, c),
                 "all W_G": _forced(np.ones_like(dense), p, c)}
        for form, chosen in forms.items():
            op = (p.dof, p.hn, *c.arrays(), *chosen)
            work = _work(op, len(p))
            for _ in range(2):  # twice: the work array hx comes back zeroed
                _times(op, s, x, work, out)
                np.testing.assert_allclose(out, s * (Wnn @ (s * x)), rtol=0, atol=1e-13 * np.abs(Wnn).max(),
                                           err_msg=form)
            assert not work[1].any()
        report = MPRGP(1e-12, 5000).solve(p)  # the complementarity conditions, with the test's W
        assert report.residual <= 1e-12
        r, u = p.impulse[:, 0], (W @ p.impulse.ravel() + b)[0::2]
        scale = np.abs(b).max()
        assert r.min() >= 0.0 and u.min() >= -1e-9 * scale and np.abs(r * u).max() <= 1e-9 * scale * r.max()


def _forced(chosen, p, c):
    """normal_groups' form of W_nn with the bodies ``chosen`` (n_blocks,) given their W_G and the
    others left to their compliance block, both as packed upper triangles made from the test's
    own dense H and C."""
    C, H = dense_form(p)[:2]
    ptr, contacts, wval, woff, cval, coff = [0], [], [], [0], [], [0]
    for g in range(len(chosen)):
        dofs = np.arange(c.start[g], c.start[g + 1])
        rows = np.flatnonzero(np.any(H[dofs][:, 0::2] != 0.0, axis=0)) if chosen[g] else np.zeros(0, int)
        Hg = H[dofs][:, 2 * rows]
        wval.append((Hg.T @ C[np.ix_(dofs, dofs)] @ Hg)[np.triu_indices(rows.size)])
        block = np.zeros((0, 0)) if chosen[g] else C[np.ix_(dofs, dofs)]
        cval.append(block[np.triu_indices(len(block))])
        contacts.extend(rows)
        ptr.append(len(contacts))
        woff.append(woff[-1] + wval[-1].size)
        coff.append(coff[-1] + cval[-1].size)
    return (np.asarray(chosen, bool), np.array(ptr), np.array(contacts, np.int64), np.array(woff),
            np.concatenate(wval), np.array(coff), np.concatenate(cval))


def _dofs_of(p, c, g):
    """(nc, m) whether each entry of the problem's rows is a dof of compliance block g."""
    return (p.dof >= c.start[g]) & (p.dof < c.start[g + 1])


def test_mprgp_error_is_the_measure_of_its_impulses():
    """The error MPRGP stops on, computed in one pass from its scaled iterate and gradient
    (r_n = s y, ũ_n = g / s), against the measure of the same impulses computed the solvers' way,
    from the velocities they make (Measure.error): the same number for the impulse measure (with
    and without the penetration test), which does not see u_t without friction; at least it for
    the velocity measures, which MPRGP judges on the normal part of W r alone (module docstring
    of compute.solvers.mprgp)."""
    from compute.solvers.interior_point import local_free_velocity
    from compute.solvers.mprgp import _error
    from compute.solvers.nlgs import apply_impulses

    for seed in range(4):
        p = bodies_problem(np.random.default_rng(500 + seed), 24)
        _, _, W, b = dense_form(p)
        rng = np.random.default_rng(seed)
        wnn = np.ascontiguousarray(p.W[:, 0, 0])
        s = 1.0 / np.sqrt(wnn)
        r = np.where(rng.random(len(p)) < 0.3, 0.0, rng.uniform(0.0, 1.0, len(p)) * np.abs(b).max() / wnn.max())
        y = r / s
        g = s * (W[0::2, 0::2] @ r + b[0::2])
        q = local_free_velocity(p)
        p.impulse[:] = np.column_stack([r, np.zeros(len(p))])
        v = p.free_velocity()
        c = p.compliance
        apply_impulses(p.dof, p.hn, p.ht, p.impulse, v, *c.arrays())
        v = p.velocities(v)
        overlap = max(0.0, -(W[0::2, 0::2] @ r + b[0::2]).min())
        for kind in ("impulse", "velocity", "velocity_max"):
            for penetration in (0.0, 0.5 * overlap * p.h_theta):
                m = Measure(kind, penetration)
                fused = _error(*m.codes(p, 1e-6), wnn, 1.0 / wnn, s, y, g, q)
                full = m.error(p, 1e-6, v)
                assert np.isfinite(full) and full > 0.0, (seed, kind)
                if kind == "impulse":
                    np.testing.assert_allclose(fused, full, rtol=1e-10, err_msg=f"{seed} {penetration}")
                else:
                    assert fused >= full * (1.0 - 1e-10), (seed, kind, penetration, fused, full)


def test_squared_normal_error_is_the_frictionless_squared_error():
    """The natural map's |f|² of a contact without friction, written for the half-line
    (compute.contact.residual.squared_normal_error), is squared_error's number with μ = 0,
    u_t = r_t = 0, to the bit: on closing, separating and touching contacts, rounding-level
    residuals, r_n = 0, W_nn = 0 (ρ = 1) and a NaN."""
    from compute.contact.residual import squared_error, squared_normal_error

    rng = np.random.default_rng(7)
    wnn = np.concatenate([rng.uniform(1e-3, 1e3, 2000), [0.0, 2.0, 2.0, 2.0]])
    un = np.concatenate([rng.normal(size=2000) * 10.0 ** rng.integers(-15, 2, 2000), [1.0, 0.0, -0.0, np.nan]])
    rn = np.concatenate([np.where(rng.random(2000) < 0.3, 0.0, rng.uniform(0.0, 2.0, 2000)), [0.5, 0.0, 0.0, 1.0]])
    rn[:500] = wnn[:500] ** -1.0 * un[:500] * (1.0 + 1e-15 * rng.normal(size=500))  # f at rounding level
    size = np.abs(un) + rng.uniform(0.0, 1.0, un.size)
    for c in range(un.size):
        rho = 1.0 / wnn[c] if wnn[c] > 0.0 else 1.0
        a = squared_error(wnn[c], un[c], 0.0, rn[c], 0.0, 0.0, size[c])
        b = squared_normal_error(rho, un[c], rn[c], size[c])
        assert a == b or (np.isnan(a) and np.isnan(b)), (c, a, b)
    assert np.isnan(squared_normal_error(0.5, np.nan, 1.0, 1.0))
