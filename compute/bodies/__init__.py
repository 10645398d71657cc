"""Body groups: the pieces of a model, each owning a contiguous range of the dofs q, v.

What the stepper asks of a group is one of the protocols of :mod:`compute.bodies.protocols`,
so that it never asks what kind it holds:

- a linear group (rigid disks, walls): ``begin_step(q, v, h, theta, load)`` returns a
  :class:`~compute.bodies.step_records.LinearStep`, its free velocity and 1x1 compliance values
  for the step (exact after one contact solve);
- a nonlinear group (soft bodies): ``begin_step`` returns a
  :class:`~compute.bodies.step_records.SoftStep` that the step's Newton iterations pass back to
  ``free_velocity(step, v, out)`` (its part of the free velocity at the iterate v),
  ``compliance(step, contact_dofs)`` (dense blocks of M̂⁻¹ per body,
  :mod:`compute.contact.compliance`), ``compliance_times(hr)`` (interior recovery), ``settle``, ...

Measures and output: ``area(q)``, ``centres(q)``, ``kinetic_energy(v)``, ``frame_fields(q, v)``.

Groups: :class:`~compute.bodies.rigid.RigidDisks`, :class:`~compute.bodies.walls.Walls`,
:class:`~compute.bodies.soft.SoftBodies` (all bodies sharing one reference mesh and material,
batched). A new kind of body is a new group satisfying one of the protocols.
"""

from compute.bodies.load import Load

__all__ = ["Load"]
