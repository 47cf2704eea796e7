"""gvsjax: Geometric Variable-Strain soft-rod simulation and PPO control in JAX."""

import jax

# All physics runs in float64 (see the design notes): the fast throw's release
# state is sensitive at the 1e-6 level and Magnus coefficients lose digits in fp32.
jax.config.update("jax_enable_x64", True)
