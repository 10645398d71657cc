"""The single-particle measures: the compaction curve of one soft disk and the fit of Eq. 2.

Eq. 2 (the paper's single-particle law): P_p/E = -b ln[(φ_p,max − φ_p)/(φ_p,max − π/4)], with
φ_p the disk's current area over the box area and P_p the mean wall pressure.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from compute.bodies_io import CELL_ELEMENT, read_layout
from compute.scene import SCENE_FILE, Material, read_parameters
from post.errors import OutputError


def soft_material(folder: Path) -> Material:
    """The (single) neo-Hookean material of a run or scene folder (its scene.toml, read through
    the scene schema; compute copies the scene's into the output folder)."""
    file = Path(folder) / SCENE_FILE
    soft = [m for m in read_parameters(file, OutputError)["materials"].values() if m.kind == "neo_hookean"]
    if len(soft) != 1:
        raise OutputError(file, "materials", "one neo_hookean material", len(soft))
    return soft[0]


def young_modulus(out: Path) -> float:
    """E of the (single) neo-Hookean material of the run."""
    return soft_material(out).young


def element_count(scene: Path) -> int:
    """Number of triangles of the scene's meshes (its bodies file, read through the bodies
    layout)."""
    layout = read_layout(Path(scene) / "bodies.vtu", OutputError)
    return sum(len(c.data) for c in layout.mesh.cells if c.type in CELL_ELEMENT)


def mesh_label(out: Path) -> str:
    """'T6 standard, 92 elements': the element type, volumetric term and count of the run's soft
    disk (for legends; '?' elements when the scene folder beside the output is unreadable)."""
    m = soft_material(out)
    try:
        n = element_count(out.parent / "scene")
    except OutputError:
        n = "?"
    return f"{m.element} {m.volumetric.replace('_', ' ')}, {n} elements"


def curve(out: Path):
    """(rows, equilibrated P_walls/E (n,), phi_p (n,)) of an output folder."""
    from post.table import measure_output

    rows = measure_output(out, min_contacts=1)
    E = young_modulus(out)
    eq = [r for r in rows if r["equilibrated"]]
    return rows, np.array([r["P_walls"] for r in eq]) / E, np.array([r["phi"] for r in eq])


def fit(p: np.ndarray, phi: np.ndarray, p_max: float, phi_max: float):
    """Eq. 2 fitted to the points (p, phi) (n,) with P/E <= ``p_max`` and phi <= ``phi_max``:
    (post.fits result, number of points used)."""
    from post.fits import fit_single_particle

    sel = (p <= p_max) & (phi <= phi_max)
    if sel.sum() < 3:
        raise ValueError(f"fit of Eq. 2: fewer than 3 equilibrated frames with P/E <= {p_max} and "
                         f"phi <= {phi_max}")
    return fit_single_particle(phi[sel], p[sel]), int(sel.sum())


def phi_at(p: np.ndarray, phi: np.ndarray, p_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A curve (P/E (n,), φ_p (n,)) at the pressures ``p_ref`` (m,), interpolated linearly in
    ln P: (mask (m,) of the pressures inside the curve's range, φ_p (m,), NaN outside it)."""
    o = np.argsort(p)
    inside = (p_ref >= p.min()) & (p_ref <= p.max())
    return inside, np.where(inside, np.interp(np.log(p_ref), np.log(p[o]), phi[o]), np.nan)


def curve_errors(p: np.ndarray, phi: np.ndarray, p_ref: np.ndarray, phi_ref: np.ndarray,
                 phi_max: float = 0.95) -> tuple[float, float]:
    """Largest relative differences of a curve (P/E (n,), φ_p (n,)) from a reference curve (m,),
    over φ_p <= ``phi_max``: of φ_p at equal P (the curve interpolated in log P at the reference
    pressures inside its range) and of P at equal φ_p (the reference interpolated, in log P, at
    the curve's φ_p). NaN where the curves do not overlap."""
    inside, at = phi_at(p, phi, p_ref)
    sel = inside & (phi_ref <= phi_max)
    e_phi = float(np.max(np.abs(at[sel] / phi_ref[sel] - 1))) if sel.any() else np.nan
    o = np.argsort(phi_ref)
    ok = (phi <= phi_max) & (phi >= phi_ref.min()) & (phi <= phi_ref.max())
    p_at = np.exp(np.interp(phi[ok], phi_ref[o], np.log(p_ref[o])))
    e_p = float(np.max(np.abs(p[ok] / p_at - 1))) if ok.any() else np.nan
    return e_phi, e_p


def write_curve(path: Path, p: np.ndarray, phi: np.ndarray, comment: str) -> Path:
    """A curve (P/E (n,), φ_p (n,)) as CSV with a comment line: the layout of the regression data
    (``# comment``, then ``P_over_E,phi_p`` and one row per stage, floats written exactly)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(p, phi))
    path.write_text(f"# {comment}\nP_over_E,phi_p\n{rows}")
    return path
