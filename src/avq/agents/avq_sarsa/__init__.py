"""AVQ Sarsa(λ): the paper's agent (``avq-paper``) and its model-free variants (``avq-sarsa``, ``avq-maze``).

- ``agent.py``: :class:`AVQSarsa`, the user-facing class;
- ``kernels.py``: its rules as compiled kernels on packed arrays (both paths call them);
- ``fused.py``: the compiled training loop on the built-in mazes.
"""

from avq.agents.avq_sarsa.agent import AVQSarsa

__all__ = ["AVQSarsa"]
