"""The body protocols (compute.bodies.protocols) and stepping/'s use of them: every body group
class has the protocol's methods with the protocol's parameters, and compute/stepping reaches
the bodies through the protocols only (no body class imported, no ``.soft``, ``.rigid`` or
``.matrices`` read)."""

import ast
import inspect
from pathlib import Path

import pytest

from compute.bodies.protocols import LinearGroup, NonlinearGroup
from compute.bodies.rigid import RigidDisks
from compute.bodies.soft import SoftBodies
from compute.bodies.walls import Walls

STEPPING = Path(__file__).resolve().parents[2] / "compute" / "stepping"
GROUPS = [(RigidDisks, LinearGroup), (Walls, LinearGroup), (SoftBodies, NonlinearGroup)]


def protocol_methods(protocol):
    return {n: f for n, f in vars(protocol).items() if inspect.isfunction(f) and not n.startswith("_")}


def parameters(f):
    return [(p.name, p.kind) for p in inspect.signature(inspect.unwrap(f)).parameters.values()]


@pytest.mark.parametrize("cls, protocol", GROUPS, ids=[c.__name__ for c, _ in GROUPS])
def test_every_group_has_its_protocols_methods_and_parameters(cls, protocol):
    methods = protocol_methods(protocol)
    assert methods, protocol
    for name, f in methods.items():
        assert callable(getattr(cls, name, None)), f"{cls.__name__} lacks {protocol.__name__}.{name}"
        assert parameters(getattr(cls, name)) == parameters(f), f"{cls.__name__}.{name}"
    assert callable(getattr(cls, "__len__", None))
    init = inspect.getsource(cls.__init__)
    for name in inspect.get_annotations(protocol):
        assert hasattr(cls, name) or f"self.{name} =" in init, f"{cls.__name__} lacks {name}"
    assert cls.nonlinear is (protocol is NonlinearGroup)


def test_a_class_that_misses_a_method_fails_the_check():
    """The check above can fail: a group without compliance() is not a NonlinearGroup."""

    class Incomplete(SoftBodies):
        compliance = None

    with pytest.raises(AssertionError):
        test_every_group_has_its_protocols_methods_and_parameters(Incomplete, NonlinearGroup)


def stepping_sources():
    files = sorted(STEPPING.glob("*.py"))
    assert len(files) >= 5
    return [(f, ast.parse(f.read_text())) for f in files]


@pytest.mark.parametrize("path, tree", stepping_sources(), ids=lambda x: getattr(x, "name", ""))
def test_stepping_talks_to_the_protocols_only(path, tree):
    """No import of a body class module (compute.bodies.{rigid,soft,walls,soft_matrix}) and no
    attribute .soft, .rigid, .walls or .matrices in compute/stepping."""
    body_modules = {"compute.bodies.rigid", "compute.bodies.soft", "compute.bodies.walls", "compute.bodies.soft_matrix"}
    body_classes = {"RigidDisks", "SoftBodies", "Walls", "NewtonMatrices"}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            assert node.module not in body_modules, f"{path.name}:{node.lineno} imports {node.module}"
            assert not body_classes & {a.name for a in node.names}, f"{path.name}:{node.lineno}"
        if isinstance(node, ast.Import):
            assert not body_modules & {a.name for a in node.names}, f"{path.name}:{node.lineno}"
        if isinstance(node, ast.Attribute):
            assert node.attr not in {"soft", "rigid", "walls", "matrices"}, f"{path.name}:{node.lineno} reads .{node.attr}"
