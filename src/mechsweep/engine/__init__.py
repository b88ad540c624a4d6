"""The engine: kernels composed from factories (closures over the model's jitted functions)."""
