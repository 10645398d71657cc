"""Step strategies by name (compute.stepping.strategies, the scene's solver.step): auto takes the
active-set Newton exactly for one soft body with its rotation held, no friction and no movable
rigid disk; an explicit active_set elsewhere is refused naming the file and the key."""

from itertools import product
from types import SimpleNamespace

import numpy as np
import pytest

from compute.errors import SceneError
from compute.stepping import strategies
from compute.stepping.active_set import solve_step as active_set_step
from compute.stepping.newton import solve_step as fixed_point_step


def settings(step, hold_rotation):
    return SimpleNamespace(step=step, hold_rotation=hold_rotation)


@pytest.mark.parametrize("hold, n_soft, n_rigid, frictional", list(product((True, False), (0, 1, 2), (0, 3), (False, True))))
def test_auto_and_explicit_names(hold, n_soft, n_rigid, frictional):
    applies = hold and n_soft == 1 and n_rigid == 0 and not frictional
    pick = lambda name: strategies.for_scene(settings(name, hold), "S/scene.toml", n_soft, n_rigid, frictional)  # noqa: E731
    assert pick("auto") is (active_set_step if applies else fixed_point_step)
    assert pick("fixed_point") is fixed_point_step
    if applies:
        assert pick("active_set") is active_set_step
    else:
        with pytest.raises(SceneError) as err:
            pick("active_set")
        assert err.value.file == "S/scene.toml" and err.value.field == "solver.step" and err.value.got == "active_set"


def test_a_rigid_scene_asking_for_the_active_set_newton_is_refused(tmp_path):
    """From the scene file to the stepper: the error names the scene's scene.toml."""
    from compute.model import Model
    from compute.scene import read_scene
    from compute.stepping.moreau_jean import Stepper
    from pre.packing import polydisperse_radii, random_loose_packing
    from pre.scene import default_parameters, write_scene

    rng = np.random.default_rng(3)
    radii = polydisperse_radii(10, rng=rng)
    centres, box = random_loose_packing(radii, 0.5, rng)
    p = default_parameters(box, 0.3, 1.0, [1.0])
    p["solver"].update(step="active_set")
    folder = write_scene(tmp_path / "scene", p, centres, radii, ["rigid"] * 10)
    model = Model(read_scene(folder))
    with pytest.raises(SceneError, match=r"scene\.toml: field 'solver\.step'"):
        Stepper(model)
