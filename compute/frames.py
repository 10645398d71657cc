"""Assembling one output frame (bodies, contacts, walls) from the model and state."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from compute import output
from compute.bodies_io import write_bodies
from compute.model import Model
from compute.state import State


def wall_forces(contacts, time_step: float) -> np.ndarray:
    """Normal force (4,) that the particles exert on each wall, from the impulses of
    ``contacts`` over the time step ``time_step`` (:meth:`ContactRows.forces`)."""
    f = np.zeros(4)
    wall = contacts.body_j < 0
    np.add.at(f, -1 - contacts.body_j[wall], contacts.forces(time_step)[wall, 0])
    return f


def write_frame_files(out: Path, frame: int, model: Model, state: State, time_step: float,
                      pressure: float) -> None:
    """Write frames/{bodies,contacts,walls}_<frame>.vtu for the current state.

    Contact geometry is re-evaluated at the current configuration with the last solved impulses,
    so that branch vectors and body positions of the frame agree.
    """
    contacts = model.frame_contacts(state)
    centres = model.centres(state.q)
    ci = centres[contacts.body_i]
    cj = np.where((contacts.body_j < 0)[:, None], contacts.point, centres[np.maximum(contacts.body_j, 0)])
    output.write_contacts(output.frame_path(out, "contacts", frame), contacts, ci, cj, time_step)
    output.write_walls(output.frame_path(out, "walls", frame), model.bounds(state.q),
                       wall_forces(contacts, time_step), pressure, model.wall_velocity(state.v))
    fields = model.frame_fields(state)
    write_bodies(output.frame_path(out, "bodies", frame), centres, model.scene.radius,
                 model.scene.body_material, meshes=model.meshes(state.q),
                 point_data=fields["point"], cell_data=fields["cell"])
