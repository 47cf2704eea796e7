"""Tasks: functional environments (gymnax-style) over the GVS simulator."""

from gvsjax.tasks.base import Environment, auto_reset_step, make, register, registered

__all__ = ["Environment", "auto_reset_step", "make", "register", "registered"]

# importing a task module registers it ("basketball", "pickplace")
from gvsjax.tasks import basketball, pickplace  # noqa: E402,F401
