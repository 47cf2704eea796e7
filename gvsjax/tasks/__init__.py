"""Tasks: functional environments (gymnax-style) over the GVS simulator."""

from gvsjax.tasks.base import Environment, auto_reset_step, make, register, registered

__all__ = ["Environment", "auto_reset_step", "make", "register", "registered"]

from gvsjax.tasks import basketball  # noqa: E402,F401  (registers "basketball")
from gvsjax.tasks import pickplace  # noqa: E402,F401  (registers "pickplace")
