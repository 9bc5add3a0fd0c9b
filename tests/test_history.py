"""EpisodeHistory: columnar per-episode records."""

import numpy as np
import pytest

from avq.agents._history import HISTORY_FIELDS, EpisodeHistory


def _record(episode, steps, ret, wall):
    return {
        "episode": episode,
        "steps": steps,
        "return": ret,
        "n_cells": 3,
        "appends": 1,
        "merges": 0,
        "refused": 0,
        "decisions": steps,
        "wall_s": wall,
    }


def test_rows_and_columns_round_trip_with_python_types():
    h = EpisodeHistory()
    assert len(h) == 0 and h.columns() == {}
    h.append(_record(1, 10, -1.5, 0.25))
    h.extend_block(2, np.array([[4, 2.0, 5, 2, 1, 0, 3], [6, -0.5, 4, 0, 1, 1, 6]]), np.array([0.5, 0.75]))
    assert len(h) == 3
    row = h[1]
    assert list(row) == list(HISTORY_FIELDS)
    assert row == {
        "episode": 2,
        "steps": 4,
        "return": 2.0,
        "n_cells": 5,
        "appends": 2,
        "merges": 1,
        "refused": 0,
        "decisions": 3,
        "wall_s": 0.5,
    }
    assert type(row["steps"]) is int and type(row["return"]) is float
    assert h[-1]["episode"] == 3 and h[-1]["refused"] == 1
    assert [r["steps"] for r in h] == [10, 4, 6]
    assert [r["episode"] for r in h[1:]] == [2, 3]
    cols = h.columns()
    assert cols["steps"].dtype == np.int64 and cols["return"].dtype == np.float64
    assert cols["return"].tolist() == [-1.5, 2.0, -0.5]
    with pytest.raises(IndexError, match="3 episodes"):
        h[3]


def test_growth_keeps_earlier_rows():
    h = EpisodeHistory()
    for k in range(200):
        h.append(_record(k + 1, k, float(k), 0.0))
    assert h.columns()["steps"].tolist() == list(range(200))
    assert h[150]["return"] == 150.0
