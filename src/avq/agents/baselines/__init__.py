"""The model-free baselines: Sarsa(λ) on a table (``tabular``), a fixed grid (``grid``) and tile coding (``tiles``).

- ``table.py``: what the table agents share (one decision per step on the rows of a table);
- ``tabular.py``, ``grid.py``, ``tiles.py``: the agents;
- ``fused.py``: the compiled training loop of ``tabular`` on GridMaze.
"""

from avq.agents.baselines.grid import GridSarsa
from avq.agents.baselines.tabular import TabularSarsa
from avq.agents.baselines.tiles import TileSarsa

__all__ = ["GridSarsa", "TabularSarsa", "TileSarsa"]
