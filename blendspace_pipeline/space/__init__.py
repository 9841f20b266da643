"""The blend space: placement on the grid, triangulation, geometry, the analysed space model,
the JSON document and the runtime evaluator (weights as an engine blends them)."""
