"""AVQ on the action space (``avq-actions``, ``uniform-actions``): Sarsa(λ) over an adaptive codebook of
continuous actions."""

from avq.agents.actions.agent import ActionCodebookSarsa

__all__ = ["ActionCodebookSarsa"]
