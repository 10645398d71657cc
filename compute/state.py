"""The mechanical state of a run: what a step reads and writes, and what a checkpoint saves.

Generalised coordinates q and velocities v (n_dofs,) are laid out group after group
(compute.model): ``[rigid disk k: x, y, rotation]*nr + [wall 0..3 position] + [soft nodes: x, y]*nn``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class State:
    """Everything a step reads and writes; a checkpoint saves exactly this. A step (and each of
    its attempts, compute.stepping) does not change the State it is given: it returns a new one
    (``dataclasses.replace``), so that a failed attempt leaves nothing to restore; the run's
    program (compute.run, load and stall bookkeeping) updates its fields between steps.

    ``q``, ``v`` (n_dofs,); ``stage`` index into the loading program; ``stage_steps`` steps
    done in the current stage; ``phi_window`` φ after each of the stage's last steps, at most
    ``loading.check_every`` + 1 of them (the stage-end test, compute.run); the stage's load
    ramp (:mod:`compute.stepping.load_control`): ``load_fraction`` λ applied, ``load_increment``
    Δλ of the next step, ``load_accepted`` steps accepted at that increment; the step control's
    (:mod:`compute.stepping.control`) ``cut_depth`` (a step starts as 2**cut_depth sub-steps) and
    ``cut_accepted`` steps accepted at that depth; the stall rule's memory (:mod:`compute.stall`):
    ``stall_residual`` the smallest contact error since the stage's last progress, ``stall_phi``
    and ``stall_area`` φ and the box area at it, ``stall_mark`` its stage step; ``frame`` the
    number of frames written; the contact memory (Verlet list and last impulses) is kept in
    ``pairs``/``impulses`` per contact family and ``q_detect`` (positions at detection).
    """

    q: np.ndarray
    v: np.ndarray
    time: float = 0.0
    step: int = 0
    stage: int = 0
    stage_steps: int = 0
    phi_window: np.ndarray = field(default_factory=lambda: np.zeros(0))
    frame: int = 0
    load_fraction: float = 0.0
    load_increment: float = 1.0
    load_accepted: int = 0
    cut_depth: int = 0
    cut_accepted: int = 0
    stall_residual: float = np.inf
    stall_phi: float = np.nan
    stall_area: float = np.nan
    stall_mark: int = 0
    q_detect: np.ndarray | None = None
    pairs: dict[str, np.ndarray] = field(default_factory=dict)
    impulses: dict[str, np.ndarray] = field(default_factory=dict)

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"q": self.q, "v": self.v,
               "scalars": np.array([self.time, self.step, self.stage, self.stage_steps, self.frame]),
               "phi_window": self.phi_window,
               "load": np.array([self.load_fraction, self.load_increment, self.load_accepted]),
               "cuts": np.array([self.cut_depth, self.cut_accepted]),
               "stall": np.array([self.stall_residual, self.stall_phi, self.stall_area, self.stall_mark])}
        if self.q_detect is not None:
            out["q_detect"] = self.q_detect
        for k, a in self.pairs.items():
            out["pairs_" + k] = a
            out["impulses_" + k] = self.impulses[k]
        return out

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> "State":
        scalars = a["scalars"]
        # checkpoints written before the sliding stage-end test had φ at the last check in 5th
        # place: their stage's window starts empty (its test waits check_every steps more)
        t, step, stage, stage_steps, frame = np.delete(scalars, 4) if len(scalars) == 6 else scalars
        families = [k[len("pairs_"):] for k in a if k.startswith("pairs_")]
        # checkpoints written before load ramps applied each stage's load at once: λ = 1
        fraction, increment, accepted = a["load"] if "load" in a else (1.0, 1.0, 0)
        # and before the step control kept the depth of its cuts: every step started whole
        depth, depth_accepted = a["cuts"] if "cuts" in a else (0, 0)
        # and before the stall rule: its memory starts at the resumed step
        residual, phi, area, mark = a["stall"] if "stall" in a else (np.inf, np.nan, np.nan, stage_steps)
        return cls(q=a["q"].copy(), v=a["v"].copy(), time=float(t), step=int(step), stage=int(stage),
                   stage_steps=int(stage_steps), phi_window=a["phi_window"].copy() if "phi_window" in a else np.zeros(0),
                   frame=int(frame),
                   load_fraction=float(fraction), load_increment=float(increment), load_accepted=int(accepted),
                   cut_depth=int(depth), cut_accepted=int(depth_accepted), stall_residual=float(residual),
                   stall_phi=float(phi), stall_area=float(area), stall_mark=int(mark),
                   q_detect=a["q_detect"].copy() if "q_detect" in a else None,
                   pairs={k: a["pairs_" + k].copy() for k in families},
                   impulses={k: a["impulses_" + k].copy() for k in families})
