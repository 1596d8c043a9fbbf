"""The one place where vpforms configures JAX.

vpforms computes in float64: volume preservation is checked to |det J − 1| ≤ 1e-12 and long runs
accumulate log det over 10⁴–10⁶ steps, which float32 cannot resolve. Importing vpforms therefore
enables ``jax_enable_x64`` for the whole process (JAX offers no per-library switch).
"""

import jax

jax.config.update("jax_enable_x64", True)
