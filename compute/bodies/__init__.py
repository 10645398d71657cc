"""Body groups: the pieces of a model, each owning a contiguous range of the dofs q, v.

Every group answers the same questions, so that the stepper never asks what kind it holds:

- ``begin_step(q, v, h, theta, load)``: what stays fixed during a step (loads, x_n);
- ``free_velocity(v, out)``: its part of the free velocity at the Newton iterate ``v`` (linear
  groups ignore ``v``: their free velocity is exact after one contact solve);
- its part of M̂⁻¹ on the dofs that contacts touch (:mod:`compute.contact.compliance`):
  ``diagonal()``, 1x1 values on all its dofs (linear groups: rigid disks, walls), or
  ``compliance(contact_dofs)``, dense blocks per body (soft bodies);
- ``recover(hr, v_free, v)``: interior velocities after the contact solve (soft bodies);
- ``area(q)``, ``centres(q)``, ``kinetic_energy(v)``, ``frame_fields(q, v)``: measures and output.

Groups: :class:`~compute.bodies.rigid.RigidDisks`, :class:`~compute.bodies.walls.Walls`,
:class:`~compute.bodies.soft.SoftBodies` (all bodies sharing one reference mesh and material,
batched). A new kind of body is a new group with these methods.
"""

from compute.bodies.load import Load

__all__ = ["Load"]
