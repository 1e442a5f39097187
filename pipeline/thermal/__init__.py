"""The lumped thermal-network kernel shared by the generator and the calibrated twin.

Both :mod:`pipeline.twin` (the synthetic-data generator, a fixed machine) and
:mod:`pipeline.discrepancy.model` (the twin calibrated from sensor roles) are
parameterisations on top of these modules; neither reimplements them:

``network``     nodes, capacities and conductances (:class:`ThermalNetwork`, the conductance
                Laplacian) and the state space with sensor-lag states (:func:`build_system`)
``discretise``  exact first-order-hold discretisation (batched matrix exponential)
``stepping``    the integration grid, one-state and batched/modal stepping, ``solve_ivp``
                cross-check
``effects``     the registry of the six switchable effects and the slots of a model's terms
``program``     the piecewise-constant spindle (or feed) program: parsed here, and only here

The kernel imports nothing from the rest of :mod:`pipeline`.
"""
