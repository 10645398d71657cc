"""Time stepping: one Moreau–Jean step (:mod:`~compute.stepping.moreau_jean`), the Newton loop
of a step with soft bodies (:mod:`~compute.stepping.newton`), and the step control that cuts a
failing step (:mod:`~compute.stepping.control`)."""
