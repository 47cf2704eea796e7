"""balance: swing a soft arm up on a torque-driven base and hold it upright (dynamic stabilization).

``params`` (the parameters and the arm), ``env`` (the environment, its metrics and
rollout), ``figures`` (drawings and the GIF).
"""

from gvsjax.tasks.balance.env import Balance, BalanceState, advance, observe, reward, rollout, tilt, upright_summary
from gvsjax.tasks.balance.params import BalanceParams, torque_arm

__all__ = ["Balance", "BalanceState", "BalanceParams", "advance", "observe", "reward", "rollout", "tilt",
           "torque_arm", "upright_summary"]
