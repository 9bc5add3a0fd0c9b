"""What ``learn`` calls while it trains: checkpoints, a progress bar, the user's own function.

As in Stable-Baselines3, everything that watches a run is a callback handed to
:meth:`avq.agents.BaseAgent.learn`, so that the agent holds the verbs and little else:

- :class:`CheckpointCallback` saves the agent and brings ``progress.csv`` up to date every
  ``every`` episodes (what ``avq train`` uses to make a run resumable);
- :class:`ProgressBarCallback` draws a tqdm bar of the agent's episodes or steps;
- :class:`EvalCallback` runs the greedy policy on an environment of its own every ``every``
  episodes and keeps the best agent seen (Stable-Baselines3's ``EvalCallback``);
- a plain function ``callback(agent, record)`` is wrapped in :class:`FunctionCallback`;
- :class:`CallbackList` runs several in order.

A callback sees every finished episode (:meth:`BaseCallback.on_episode_end`; returning
``False`` stops ``learn``). The compiled training loops run many episodes in one call; a
callback says how many episodes may pass before it must see one
(:meth:`BaseCallback.episodes_to_next_call`), and ``learn`` stops its compiled loop there.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from avq._io import ProgressLog, atomic_write_bytes, make_dirs
from avq._validate import check_int
from avq.agents._history import HISTORY_FIELDS

if TYPE_CHECKING:
    import gymnasium as gym

    from avq.agents.base import BaseAgent

__all__ = [
    "BaseCallback",
    "CallbackList",
    "CheckpointCallback",
    "EvalCallback",
    "FunctionCallback",
    "ProgressBarCallback",
    "as_callback",
    "PROGRESS_COLUMNS",
]

#: The columns of ``progress.csv``: every field of the per-episode record.
PROGRESS_COLUMNS = HISTORY_FIELDS
#: One episode's record, as ``history_`` holds it.
Record = dict[str, Any]
#: No call needed before the end of ``learn``.
NEVER = 1 << 62


class BaseCallback:
    """A callback of :meth:`~avq.agents.BaseAgent.learn`. Every method may be left as it is."""

    def on_learn_start(self, agent: BaseAgent, total_episodes: int | None, total_timesteps: int | None) -> None:
        """Before the first step of a ``learn`` call, with its budget (one of the two is None)."""

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        """How many more episodes may finish before this callback must see one (a compiled loop stops there)."""
        return NEVER

    def on_steps(self, agent: BaseAgent, n: int) -> None:
        """After ``n`` more environment steps (in chunks: after an episode, or a compiled loop's call)."""

    def on_episode_end(self, agent: BaseAgent, record: Record) -> bool | None:
        """After an episode, its record in ``agent.history_``; ``False`` stops ``learn``."""
        return None

    def on_learn_end(self, agent: BaseAgent) -> None:
        """When ``learn`` returns or raises."""


class FunctionCallback(BaseCallback):
    """``fn(agent, record)`` after every episode; returning ``False`` stops ``learn``."""

    def __init__(self, fn: Callable[[BaseAgent, Record], bool | None]) -> None:
        self.fn = fn

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        return 1

    def on_episode_end(self, agent: BaseAgent, record: Record) -> bool | None:
        return self.fn(agent, record)


class CheckpointCallback(BaseCallback):
    """Every ``every`` episodes (counted from the agent's first), save the agent to
    ``directory/checkpoint.zip`` and bring ``directory/progress.csv`` (one row per episode) up to
    date, both written so that a crash leaves a complete file; at the end of ``learn``, the rows
    since the last checkpoint too. Loading the checkpoint (:func:`avq.load`) and learning on gives
    bit for bit what learning on without the stop would have given.

    Args:
        every: Episodes between checkpoints (>= 1).
        directory: Where the files go (made if missing; a file there is refused).
    """

    def __init__(self, every: int, directory: str | os.PathLike) -> None:
        self.every = check_int("checkpoint every", every, 1)
        self.directory = Path(directory)
        if self.directory.exists() and not self.directory.is_dir():
            raise ValueError(f"checkpoint directory {self.directory} is a file; give a directory")
        self.log = ProgressLog(self.directory / "progress.csv", PROGRESS_COLUMNS)

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        return self.every - agent.num_episodes % self.every

    def on_episode_end(self, agent: BaseAgent, record: Record) -> None:
        if record["episode"] == agent.num_episodes and not agent.in_episode and agent.num_episodes % self.every == 0:
            self.log.sync(agent.history_)
            agent.save(self.directory / "checkpoint.zip")

    def on_learn_end(self, agent: BaseAgent) -> None:
        self.log.sync(agent.history_)  # (the episodes after the last checkpoint too; a resume drops them again)


#: The files an :class:`EvalCallback` writes into its directory.
EVAL_FILES = ("evaluations.csv", "best.zip")


class EvalCallback(BaseCallback):
    """Every ``every`` episodes (counted from the agent's first), the greedy policy run for ``n_eval_episodes`` on
    ``eval_env`` (:func:`avq.evaluation.evaluate_policy`, its first reset seeded with ``seed``, so every evaluation
    starts from the same states) and its figures kept in :attr:`evaluations_`; with ``directory``, the rows written
    to ``directory/evaluations.csv`` and the agent saved to ``directory/best.zip`` whenever its mean return is above
    every one before (both files written whole, so that a crash leaves a complete one). Stable-Baselines3's
    ``EvalCallback``, counted in episodes as :class:`CheckpointCallback` is: a greedy policy can be far better at one
    check than at the end of the run (docs: results/dimensions.md, RL Zoo's budgets), and ``best.zip`` keeps it.

    Args:
        eval_env: An environment like the one the agent learns on, not the same object (its spaces are checked
            against the agent's when ``learn`` starts).
        every: Episodes between evaluations (>= 1).
        n_eval_episodes: Episodes of each evaluation (>= 1).
        directory: Where the files go (made if missing; a file there is refused, and so is a directory that holds
            ``evaluations.csv`` or ``best.zip`` already: an earlier run's); None: no files.
        seed: The seed of each evaluation's first reset.

    Attributes:
        evaluations_: One dict per evaluation: ``episode``, ``timesteps``, ``mean_return``, ``std_return``,
            ``success_rate`` (None where the task defines no success).
        best_mean_return_: The best ``mean_return`` so far (``-inf`` before any evaluation).
    """

    def __init__(
        self,
        eval_env: gym.Env,
        every: int,
        n_eval_episodes: int = 10,
        directory: str | os.PathLike | None = None,
        seed: int = 0,
    ) -> None:
        if not (hasattr(eval_env, "reset") and hasattr(eval_env, "step") and hasattr(eval_env, "observation_space")):
            raise TypeError(f"eval_env must be a gymnasium environment, not {type(eval_env).__name__}; make one with "
                            "gymnasium.make(...) as for the agent")  # fmt: skip
        self.eval_env = eval_env
        self.every = check_int("eval every", every, 1)
        self.n_eval_episodes = check_int("n_eval_episodes", n_eval_episodes, 1)
        self.seed = check_int("eval seed", seed, 0)
        self.directory = None if directory is None else Path(directory)
        if self.directory is not None and self.directory.exists() and not self.directory.is_dir():
            raise ValueError(f"eval directory {self.directory} is a file; give a directory")
        held = [name for name in EVAL_FILES if self.directory is not None and (self.directory / name).exists()]
        if held:
            raise ValueError(
                f"eval directory {self.directory} holds {' and '.join(held)} already (an earlier run's, which this "
                "one would replace); give another directory, or move them away to start again"
            )
        self.evaluations_: list[Record] = []
        self.best_mean_return_ = float("-inf")

    def on_learn_start(self, agent: BaseAgent, total_episodes: int | None, total_timesteps: int | None) -> None:
        from avq.envs import same_env

        if same_env(self.eval_env, agent.env):
            raise ValueError("eval_env is the environment the agent learns on; give it one of its own (an evaluation "
                             "resets it, which would cut the episode being learned)")  # fmt: skip
        from avq.agents.save_util import check_env_fits, env_signature

        check_env_fits(env_signature(agent.env), self.eval_env, "EvalCallback")

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        return self.every - agent.num_episodes % self.every

    def on_episode_end(self, agent: BaseAgent, record: Record) -> None:
        if record["episode"] != agent.num_episodes or agent.in_episode or agent.num_episodes % self.every:
            return
        from avq.evaluation import evaluate_policy

        ev = evaluate_policy(agent, self.eval_env, self.n_eval_episodes, seed=self.seed)
        row = dict(episode=agent.num_episodes, timesteps=agent.num_timesteps, mean_return=ev["mean_return"],
                   std_return=ev["std_return"], success_rate=ev["success_rate"])  # fmt: skip
        self.evaluations_.append(row)
        best = row["mean_return"] > self.best_mean_return_
        self.best_mean_return_ = max(self.best_mean_return_, row["mean_return"])
        if self.directory is not None:
            make_dirs(self.directory)
            columns = list(row)
            lines = [",".join(columns)] + [",".join("" if r[c] is None else str(r[c]) for c in columns)
                                           for r in self.evaluations_]  # fmt: skip
            atomic_write_bytes(self.directory / "evaluations.csv", ("\n".join(lines) + "\n").encode())
            if best:
                agent.save(self.directory / "best.zip")


class ProgressBarCallback(BaseCallback):
    """A tqdm bar of the agent's episodes (or steps, for a step budget): it starts at those already
    learned, ends where the ``learn`` call does, and stays on screen. Updated every 64 episodes
    at least inside a compiled loop."""

    def __init__(self) -> None:
        self.bar: Any = None
        self.unit = "episode"

    def on_learn_start(self, agent: BaseAgent, total_episodes: int | None, total_timesteps: int | None) -> None:
        from tqdm.auto import tqdm

        self.unit = "episode" if total_episodes is not None else "step"
        done = agent.num_episodes if total_episodes is not None else agent.num_timesteps
        total = total_episodes if total_episodes is not None else total_timesteps
        self.bar = tqdm(total=done + (total or 0), initial=done, unit=self.unit, desc=type(agent).__name__)

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        return 64

    def on_steps(self, agent: BaseAgent, n: int) -> None:
        if self.unit == "step" and self.bar is not None:
            self.bar.update(n)

    def on_episode_end(self, agent: BaseAgent, record: Record) -> None:
        if self.unit == "episode" and self.bar is not None:
            self.bar.update(1)

    def on_learn_end(self, agent: BaseAgent) -> None:
        if self.bar is not None:
            self.bar.close()


class CallbackList(BaseCallback):
    """Several callbacks, called in order; ``learn`` stops when one of them returns ``False``."""

    def __init__(self, callbacks: Sequence[BaseCallback]) -> None:
        self.callbacks = list(callbacks)

    def on_learn_start(self, agent: BaseAgent, total_episodes: int | None, total_timesteps: int | None) -> None:
        for c in self.callbacks:
            c.on_learn_start(agent, total_episodes, total_timesteps)

    def episodes_to_next_call(self, agent: BaseAgent) -> int:
        return min((c.episodes_to_next_call(agent) for c in self.callbacks), default=NEVER)

    def on_steps(self, agent: BaseAgent, n: int) -> None:
        for c in self.callbacks:
            c.on_steps(agent, n)

    def on_episode_end(self, agent: BaseAgent, record: Record) -> bool | None:
        stop = False
        for c in self.callbacks:
            stop = c.on_episode_end(agent, record) is False or stop
        return False if stop else None

    def on_learn_end(self, agent: BaseAgent) -> None:
        for c in self.callbacks:
            c.on_learn_end(agent)


def as_callback(callback: Any, progress_bar: bool = False) -> CallbackList:
    """What ``learn(callback=..., progress_bar=...)`` was given, as one :class:`CallbackList`: a
    callback, a function ``fn(agent, record)``, a list of either, or None."""
    items: Iterable[Any] = [] if callback is None else callback if isinstance(callback, (list, tuple)) else [callback]
    out: list[BaseCallback] = [ProgressBarCallback()] if progress_bar else []
    for item in items:
        if isinstance(item, BaseCallback):
            out.append(item)
        elif callable(item):
            out.append(FunctionCallback(item))
        else:
            raise TypeError(
                f"callback must be a BaseCallback or callable as callback(agent, record), not {type(item).__name__}"
            )
    return CallbackList(out)
