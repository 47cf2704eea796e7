"""The simulator: the Geometric Variable-Strain model of a chain of soft and rigid links.

Modules by layer (each imports only from its own layer or the ones above it):

1. Lie-group math: ``lie``, ``linalg``.
2. The model: ``model`` (links, joints, materials, loads), ``validation`` (checks at the
   boundary), ``robots`` and ``curvature_arm`` (ready-made robots), ``obstacles``, ``loads``.
3. Kinematics: ``magnus`` (strain-to-pose integration), ``scan`` (the recursions),
   ``kinematics``.
4. Dynamics: ``tendons``, ``muscles``, ``active_strain``, contact (``contact``, with
   ``penetration``, ``stacked_contact``, ``contact_samples``), ``dynamics``.
5. ``integrators``.
6. Simulation and statics: ``inputs``, ``system``, ``stability``, ``trajectory``,
   ``simulation``, ``statics``, ``identify``.

The public API is re-exported as ``gvsjax.*``; this package's ``__init__`` imports nothing, so
importing one module does not pull in the rest.
"""
