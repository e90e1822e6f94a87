"""Model reduction: fixed-interface modes of each body's non-contact region (SLEPc), Craig-Bampton
constraint modes, the contact zone's basis (nodal, or first-order manifold covers: :mod:`.nmm_zone`),
the reduced matrices, and the free-vibration modes of the reduced system.

Takes an :class:`millimpact.fem.model.FEModel`; gives a :class:`.reduced_model.ReducedModel`
(reduced M, K, the transform T and the coordinate sets). Imports integration, fem and below.
"""
