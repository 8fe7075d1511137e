"""Demonstration datasets as Minari datasets.

Each episode stores observations (including the initial one), actions, rewards,
terminations, truncations and, in ``infos``, per step: ``performance``,
``normalized_performance`` and the full simulator ``state`` (from ``env.get_state()``), so
any step can be restored for reference-state initialisation or trajectory optimisation.

Python::

    from lfd_envs import datasets
    path = datasets.collect("ClothFoldDiagonalPinned-v0", episodes=10, out_dir="demos",
                            env_kwargs={"action_mode": "pick_place", "obs_mode": "state"})
    ds = datasets.load(path)
    for ep in ds.iterate_episodes():
        states = datasets.episode_states(ep)        # list of dicts for env.unwrapped.set_state

Command line::

    python -m lfd_envs.datasets collect --env ClothFold-v0 --episodes 20 \
        [--out DIR --num-pickers 2 --action-mode pick_place --obs-mode state --seed 0 --policy expert|random]
        [--name NAME --overwrite]

An existing dataset of the same name is kept (``FileExistsError``; on the command line one
``error:`` line and exit status 2) unless ``overwrite=True`` / ``--overwrite``.

Without ``--out`` (``out_dir=None``) datasets go to Minari's own datasets folder
(``$MINARI_DATASETS_PATH``, else ``~/.minari/datasets``), where ``minari list local`` and
``minari.load_dataset("lfd/ClothFold/expert-v0")`` find them. With ``--out DIR`` the command
prints the ``MINARI_DATASETS_PATH`` to set for Minari's tools. The datasets are local: Minari's
``show`` lists a ``minari download`` line for every dataset, which does not apply to them.

Note: Minari's HDF5 storage JPEG-encodes uint8 image observations, which at 32×32 blurs the
cloth and the pickers beyond recognition; :func:`exact_observations` renders them again exactly
from the stored states (``lfd_agents`` does so whenever it loads a dataset of this module).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import sys
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator

import gymnasium as gym
import numpy as np

import lfd_envs  # noqa: F401  (registers ids)
from lfd_envs.core.rollout import episode_steps

STATE_KEY = "state"
_SEP = "."  # HDF5 uses "/" for groups; state keys are flattened with this separator
DATASET_PREFIX = "lfd"

Policy = Callable[[Any], np.ndarray]


# ---------------------------------------------------------------------- state encoding
def _encode_state(state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Make a state storable: flat keys, no uint8/bool arrays (Minari would JPEG them)."""
    out = {}
    for key, value in state.items():
        arr = np.asarray(value)
        if arr.dtype == np.bool_ or arr.dtype == np.uint8:
            arr = arr.astype(np.int16)
        out[key.replace("/", _SEP)] = arr
    return out


def _decode_state(encoded: dict[str, np.ndarray], template: dict[str, np.ndarray] | None) -> dict[str, np.ndarray]:
    state = {key.replace(_SEP, "/"): np.asarray(v) for key, v in encoded.items()}
    if template is not None:
        for key, ref in template.items():
            if key in state:
                state[key] = state[key].astype(np.asarray(ref).dtype).reshape(np.shape(ref))
    return state


# ---------------------------------------------------------------------- policies
def expert_policy(env: gym.Env, **expert_kwargs: Any) -> Any:
    """The task's scripted expert (see :mod:`lfd_envs.experts`), built with ``expert_kwargs``
    (e.g. ``{"direct_approach": True}`` for the particle tasks' experts)."""
    from lfd_envs.experts import make_expert

    return make_expert(env, **expert_kwargs)


class RandomPolicy:
    """Uniform random actions from the env's action space (seeded)."""

    def __init__(self, env: gym.Env, seed: int = 0):
        self.space = env.action_space
        self.space.seed(seed)

    def reset(self) -> None:
        pass

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.space.sample(), None


def random_pick_place_policy(env: gym.Env) -> Any:
    """Random pick-and-place moves for dynamics-model data (MAIL; :mod:`lfd_envs.experts.random_pick_place`)."""
    from lfd_envs.experts.random_pick_place import random_pick_place_policy as factory

    return factory(env)


def noisy_expert_policy(env: gym.Env, seed: int = 0, epsilon: float = 0.2, action_noise: float = 0.0,
                        **expert_kwargs: Any) -> Any:
    """The scripted expert (built with ``expert_kwargs``) with random slips of probability
    ``epsilon`` per step and Gaussian noise of standard deviation ``action_noise`` (half-ranges) on
    its other actions (:mod:`lfd_envs.experts.noisy`): demonstrations of controlled, lower quality,
    or (``epsilon`` 0, small ``action_noise``) demonstrations that also show how the expert
    recovers from small deviations."""
    from lfd_envs.experts.noisy import noisy_expert_policy as factory

    return factory(env, epsilon=epsilon, seed=seed, action_noise=action_noise, **expert_kwargs)


POLICIES = {"expert": expert_policy, "random": RandomPolicy, "random_pick_place": random_pick_place_policy,
            "noisy_expert": noisy_expert_policy}
#: policies whose factory takes the collection seed (``factory(env, seed, **policy_kwargs)``)
_SEEDED_POLICIES = (RandomPolicy, noisy_expert_policy)


def _build_policy(factory: Any, name: str, env: gym.Env, seed: int, policy_kwargs: dict[str, Any]) -> Any:
    """``factory``'s policy for ``env``; arguments it does not take are a ValueError naming them."""
    try:
        return factory(env, seed, **policy_kwargs) if factory in _SEEDED_POLICIES else factory(env, **policy_kwargs)
    except TypeError as exc:
        raise ValueError(f"policy {name!r} does not take {sorted(policy_kwargs)}: {exc}") from exc


def make_policy(env: gym.Env, policy: str = "expert", seed: int = 0, **policy_kwargs: Any) -> Any:
    """The named demonstrator of :data:`POLICIES` for ``env`` (as :func:`collect` builds it)."""
    if policy not in POLICIES:
        raise ValueError(f"unknown policy {policy!r}; valid: {sorted(POLICIES)}")
    return _build_policy(POLICIES[policy], policy, env, seed, policy_kwargs)


# ---------------------------------------------------------------------- collection
class EpisodeRecorder:
    """Accumulates one episode in the layout Minari's ``EpisodeBuffer`` expects."""

    def __init__(self, episode_id: int, seed: int, options: dict[str, Any]):
        self.id, self.seed, self.options = episode_id, seed, options
        self.observations: list[Any] = []
        self.actions: list[np.ndarray] = []
        self.rewards: list[float] = []
        self.terminations: list[bool] = []
        self.truncations: list[bool] = []
        self.infos: list[dict[str, Any]] = []

    def add(self, obs: Any, info: dict[str, Any], env: gym.Env) -> None:
        self.observations.append(obs)
        self.infos.append({
            "performance": np.float64(info["performance"]),
            "normalized_performance": np.float64(info["normalized_performance"]),
            "is_success": np.bool_(info.get("is_success", False)),
            STATE_KEY: _encode_state(env.unwrapped.get_state()),
        })

    def buffer(self):
        from minari.data_collector import EpisodeBuffer

        return EpisodeBuffer(
            id=self.id, seed=self.seed, options=self.options,
            observations=_stack_tree(self.observations), actions=np.asarray(self.actions),
            rewards=list(self.rewards), terminations=list(self.terminations),
            truncations=list(self.truncations), infos=_stack_tree(self.infos),
        )


def _stack_tree(items: list[Any]) -> Any:
    """Stack a list of (nested dicts of) arrays along a new first axis."""
    first = items[0]
    if isinstance(first, dict):
        return {k: _stack_tree([it[k] for it in items]) for k in first}
    if isinstance(first, str):
        return list(items)
    return np.stack([np.asarray(it) for it in items])


def run_episode(env: gym.Env, policy: Any, seed: int, options: dict[str, Any], episode_id: int = 0,
                initial_state: dict[str, np.ndarray] | None = None) -> EpisodeRecorder:
    """Roll out ``policy`` for one episode and record everything.

    With ``initial_state`` the env is reset and then put into that state (e.g. a teacher's
    start state for a student with another picker count), so the episode starts there.
    """
    rec = EpisodeRecorder(episode_id, seed, options)
    obs, info = env.reset(seed=seed, options=options)
    if initial_state is not None:
        env.unwrapped.set_state(initial_state)
        obs, info = env.unwrapped.current_observation(), env.unwrapped.current_info()
    if hasattr(policy, "reset"):
        policy.reset()
    rec.add(obs, info, env)
    for step in episode_steps(env, policy, obs):
        rec.actions.append(np.asarray(step.action, dtype=np.asarray(env.action_space.sample()).dtype))
        rec.rewards.append(float(step.reward))
        rec.terminations.append(bool(step.terminated))
        rec.truncations.append(bool(step.truncated))
        rec.add(step.obs, step.info, env)
    return rec


@contextlib.contextmanager
def _datasets_root(out_dir: str | os.PathLike):
    """Point Minari at ``out_dir`` for the duration of the block."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(out_dir).resolve())
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def dataset_id(env_id: str, name: str) -> str:
    """Minari id ``lfd/<EnvName>/<name>-v0`` for an lfd env id (``name`` as :func:`dataset_name` takes it)."""
    return f"{DATASET_PREFIX}/{_env_name(env_id)}/{dataset_name(env_id, name)}-v0"


def _env_name(env_id: str) -> str:
    return env_id.split(":")[-1].split("-v")[0]


def dataset_name(env_id: str, name: str) -> str:
    """The bare dataset name of ``name``: ``"dup"``, ``"dup-v0"`` and the full Minari id
    ``"lfd/<EnvName>/dup-v0"`` all give ``"dup"``. ``ValueError`` naming ``name`` for an empty
    name, another env's id, another version or characters other than letters, digits, ``_.-``."""
    if not isinstance(name, str):
        raise ValueError(f"name must be a string, got {type(name).__name__}")
    bare = name
    prefix = f"{DATASET_PREFIX}/{_env_name(env_id)}/"
    if bare.startswith(prefix):
        bare = bare[len(prefix):]
    if bare.endswith("-v0"):
        bare = bare[:-3]
    if not re.fullmatch(r"[A-Za-z0-9_.]+(-[A-Za-z0-9_.]+)*", bare) or re.search(r"-v\d+$", bare):
        raise ValueError(f"name {name!r} is not a dataset name for {env_id}: use letters, digits, '_', '.' and "
                         f"'-' (e.g. 'expert'), optionally as the full id '{prefix}<name>-v0'")
    return bare


def dataset_path(env_id: str, name: str, out_dir: str | os.PathLike | None) -> Path:
    """Folder :func:`collect` writes the dataset ``name`` of ``env_id`` to (``out_dir`` None:
    :func:`minari_root`)."""
    root = minari_root() if out_dir is None else Path(out_dir)
    if root.exists() and not root.is_dir():
        raise ValueError(f"out_dir {str(root)!r} is a file, not a folder")
    existing = next(p for p in (root.resolve(), *root.resolve().parents) if p.exists())
    if not existing.is_dir() or not os.access(existing, os.W_OK):
        raise ValueError(f"out_dir {str(root)!r} cannot be written ({existing} is not a writable folder)")
    return root.resolve() / dataset_id(env_id, name)


def _check_new(path: Path, overwrite: bool) -> None:
    """``FileExistsError`` if a dataset is at ``path`` and ``overwrite`` is false."""
    if path.exists() and not overwrite:
        raise FileExistsError(f"a dataset already exists at {path}; pass overwrite=True (command line: "
                              "--overwrite) to replace it, or choose another name")


def collect(
    env_id: str,
    episodes: int,
    out_dir: str | os.PathLike | None = None,
    *,
    env_kwargs: dict[str, Any] | None = None,
    policy: str | Callable[[gym.Env], Any] | None = None,
    seed: int = 0,
    split: str = "train",
    name: str | None = None,
    min_normalized_performance: float | None = None,
    progress: bool = True,
    policy_kwargs: dict[str, Any] | None = None,
    overwrite: bool = False,
) -> Path:
    """Roll out a policy (the scripted expert by default) and save a Minari dataset.

    Args:
        env_id: registered env id, e.g. ``"ClothFold-v0"``.
        episodes: number of episodes to store (must be >= 1).
        out_dir: root folder of the dataset (Minari's datasets path for this dataset); None:
            Minari's default datasets folder (:func:`minari_root`).
        env_kwargs: constructor arguments of the env.
        policy: ``"expert"`` (default), ``"noisy_expert"``, ``"random"``, ``"random_pick_place"``
            or a factory ``env -> policy`` whose policy has ``predict(obs, deterministic=True) ->
            (action, _)`` and optionally ``reset()``.
        seed: episode ``i`` is reset with ``seed + i`` (variants drawn from ``split``).
        name: dataset name (default: the policy name or ``"custom"``).
        min_normalized_performance: keep only episodes whose final p̂ reaches this value
            (collection continues until ``episodes`` are kept, at most 10× attempts).
        progress: show a progress bar.
        policy_kwargs: extra arguments of a named policy's factory, e.g. ``{"epsilon": 0.2}`` for
            ``"noisy_expert"`` (recorded in the dataset's description).
        overwrite: replace a dataset of the same name in ``out_dir``; without it an existing
            one raises ``FileExistsError`` before anything is rolled out.

    Returns:
        The dataset's folder (pass it to :func:`load`).
    """
    import minari
    from tqdm import tqdm

    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be an int >= 1, got {episodes!r}")
    env_kwargs = dict(env_kwargs or {})
    policy = policy or "expert"
    if isinstance(policy, str):
        if policy not in POLICIES:
            raise ValueError(f"unknown policy {policy!r}; valid: {sorted(POLICIES)} or a callable env -> policy")
        name = name or policy
        factory = POLICIES[policy]
    else:
        name = name or "custom"
        factory = policy
    _check_new(dataset_path(env_id, name, out_dir), overwrite)
    policy_kwargs = dict(policy_kwargs or {})
    if policy_kwargs and factory not in POLICIES.values():
        raise ValueError("policy_kwargs apply to named policies only; bind them into your factory instead")
    env = gym.make(env_id, **env_kwargs)
    try:
        agent = _build_policy(factory, name, env, seed, policy_kwargs)
    except ValueError:
        env.close()
        raise
    kept: list[Any] = []
    attempts = 0
    bar = tqdm(total=int(episodes), desc=f"collect {env_id}", disable=not progress, file=sys.stderr)
    while len(kept) < int(episodes) and attempts < 10 * int(episodes):
        rec = run_episode(env, agent, seed + attempts, {"split": split}, episode_id=len(kept))
        attempts += 1
        final = float(rec.infos[-1]["normalized_performance"])
        if min_normalized_performance is not None and final < min_normalized_performance:
            continue
        kept.append(rec)
        bar.update(1)
    bar.close()
    if not kept:
        raise RuntimeError(f"no episode reached normalized performance {min_normalized_performance}")
    env.close()
    return write_dataset(kept, env, env_id, out_dir, name=name, env_kwargs=env_kwargs, seed=seed, split=split,
                         extra={"policy_kwargs": policy_kwargs} if policy_kwargs else None, overwrite=overwrite)


def minari_root() -> Path:
    """The folder Minari's tools read datasets from (``$MINARI_DATASETS_PATH`` or ``~/.minari/datasets``)."""
    from minari.storage import get_dataset_path

    return get_dataset_path().resolve()


def write_dataset(episodes: list[Any], env: gym.Env, env_id: str, out_dir: str | os.PathLike | None, *, name: str,
                  env_kwargs: dict[str, Any] | None = None, seed: int = 0, split: str = "train",
                  extra: dict[str, Any] | None = None, overwrite: bool = False) -> Path:
    """Save recorded episodes (``EpisodeRecorder`` or Minari ``EpisodeBuffer``) as a Minari dataset
    (``FileExistsError`` if one of the same name exists there, unless ``overwrite``)."""
    import minari

    kept = []
    for i, ep in enumerate(episodes):
        if not isinstance(ep, EpisodeRecorder):
            raise TypeError(f"episodes must be recorded with run_episode(), got {type(ep).__name__}")
        ep.id = i
        kept.append(ep.buffer())
    env_kwargs = dict(env_kwargs or {})
    ds_id = dataset_id(env_id, name)
    _check_new(dataset_path(env_id, name, out_dir), overwrite)
    name = dataset_name(env_id, name)
    out_dir = minari_root() if out_dir is None else out_dir
    with _datasets_root(out_dir):
        with contextlib.suppress(FileNotFoundError):
            minari.delete_dataset(ds_id)
        with warnings.catch_warnings():
            # Minari nags about author/permalink metadata that a local dataset has no use for.
            warnings.filterwarnings("ignore", category=UserWarning, module="minari")
            minari.create_dataset_from_buffers(
                dataset_id=ds_id, buffer=kept, env=env, eval_env=env, algorithm_name=f"lfd-{name}",
                author="lfd", code_permalink=None,
                description=json.dumps({"env_id": env_id, "env_kwargs": env_kwargs, "policy": name,
                                        "seed": seed, "split": split, **(extra or {})}),
            )
    return Path(out_dir).resolve() / ds_id


def load(path: str | os.PathLike) -> Any:
    """Load a dataset written by :func:`collect` from its folder."""
    import minari

    path = Path(path).resolve()
    if not (path / "data").exists():
        raise FileNotFoundError(f"{path} is not a dataset folder written by lfd_envs.datasets.collect")
    parts = path.parts
    ds_id = "/".join(parts[-3:])
    root = Path(*parts[:-3])
    with _datasets_root(root):
        return minari.load_dataset(ds_id)


def final_performances(episodes: Any) -> list[float]:
    """Final p̂ of each episode recorded by :func:`collect` (Minari ``EpisodeData``, e.g. from
    ``load(path).iterate_episodes()``); ``KeyError`` if an episode's infos lack it."""
    return [float(ep.infos["normalized_performance"][-1]) for ep in episodes]


def dataset_config(dataset: Any) -> dict[str, Any]:
    """``env_id``, ``env_kwargs``, ``policy``, ``seed``, ``split`` of a dataset from :func:`collect`."""
    return json.loads(dataset.storage.metadata["description"])


def make_env(dataset: Any, **overrides: Any) -> gym.Env:
    """Make the env a dataset was collected on (with optional kwarg overrides)."""
    cfg = dataset_config(dataset)
    return gym.make(cfg["env_id"], **{**cfg["env_kwargs"], **overrides})


def episode_states(episode: Any, env: gym.Env | None = None) -> list[dict[str, np.ndarray]]:
    """Per-step simulator states of an episode (``T + 1`` dicts for ``set_state``).

    Pass ``env`` to restore exact dtypes and shapes (recommended).
    """
    encoded = episode.infos[STATE_KEY]
    n = len(next(iter(encoded.values())))
    template = env.unwrapped.get_state() if env is not None and getattr(env.unwrapped, "_variant_index", 0) >= 0 else None
    return [_decode_state({k: v[t] for k, v in encoded.items()}, template) for t in range(n)]


def has_images(space: gym.Space) -> bool:
    """Whether observations of ``space`` hold an image that Minari stores as JPEG (Minari's own
    test: uint8, 0..255, at least 32×32; smaller images it keeps exactly)."""
    from minari.dataset.minari_storage import is_image_space

    if isinstance(space, gym.spaces.Dict):
        return any(has_images(s) for s in space.spaces.values())
    return is_image_space(space)


def exact_observations(episode: Any, env: gym.Env, states: list[dict[str, np.ndarray]] | None = None) -> Any:
    """An episode's observations (``T + 1``, array or dict of arrays) with every image rendered
    again from the episode's stored states in ``env`` (made with :func:`make_env`), undoing
    Minari's JPEG encoding; other entries are the stored ones. ``states``: the episode's
    :func:`episode_states` if already decoded. ``env`` is reset once and left in the episode's
    last state."""
    base = env.unwrapped
    if getattr(base, "_variant_index", -1) < 0:
        env.reset(seed=0)  # set_state needs a reset env; it also gives the states' exact dtypes
    if states is None:
        states = episode_states(episode, env)
    obs = episode.observations
    if len(states) != len(next(iter(obs.values())) if isinstance(obs, dict) else obs):
        raise ValueError(f"episode has {len(states)} states for its observations; it was not written by collect")
    keys = [k for k, s in env.observation_space.spaces.items() if has_images(s)] if isinstance(obs, dict) else None
    out = {k: np.array(v, copy=True) for k, v in obs.items()} if isinstance(obs, dict) else np.array(obs, copy=True)
    for t, state in enumerate(states):
        base.set_state(state)
        now = base.current_observation()
        if keys is None:
            out[t] = now
        else:
            for k in keys:
                out[k][t] = now[k]
    return out


def replay(env: gym.Env, episode: Any) -> list[float]:
    """Restore an episode's initial simulator state, re-run its actions, return p̂ after each step."""
    env.reset(seed=0)
    env.unwrapped.set_state(episode_states(episode, env)[0])
    perfs = []
    for action in episode.actions:
        _, _, _, _, info = env.step(action)
        perfs.append(float(info["normalized_performance"]))
    return perfs


def iterate_transitions(dataset: Any) -> Iterator[tuple[Any, np.ndarray, float, Any, bool, bool]]:
    """Yield ``(obs, action, reward, next_obs, terminated, truncated)`` over all episodes."""
    for ep in dataset.iterate_episodes():
        obs = ep.observations
        for t in range(len(ep.actions)):
            o = {k: v[t] for k, v in obs.items()} if isinstance(obs, dict) else obs[t]
            o2 = {k: v[t + 1] for k, v in obs.items()} if isinstance(obs, dict) else obs[t + 1]
            yield o, ep.actions[t], float(ep.rewards[t]), o2, bool(ep.terminations[t]), bool(ep.truncations[t])


# ---------------------------------------------------------------------- CLI
def _parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m lfd_envs.datasets", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("collect", help="roll out the expert (or random) policy and save a Minari dataset")
    c.add_argument("--env", required=True, help="env id, e.g. ClothFold-v0")
    c.add_argument("--episodes", type=int, required=True)
    c.add_argument("--out", help="output folder (default: Minari's datasets folder, where `minari list local` looks)")
    c.add_argument("--num-pickers", type=int)
    c.add_argument("--action-mode")
    c.add_argument("--obs-mode")
    c.add_argument("--resolution", type=int)
    c.add_argument("--policy", default="expert", choices=sorted(POLICIES))
    c.add_argument("--policy-kwargs", type=json.loads, default=None, metavar="JSON",
                   help='arguments of the policy, e.g. \'{"epsilon": 0.2}\' for noisy_expert')
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--split", default="train", choices=["train", "eval"])
    c.add_argument("--name", help="dataset name (default: the policy's); 'dup', 'dup-v0' and "
                   "'lfd/<EnvName>/dup-v0' all name lfd/<EnvName>/dup-v0")
    c.add_argument("--overwrite", action="store_true", help="replace an existing dataset of the same name")
    i = sub.add_parser("info", help="summarise a dataset folder")
    i.add_argument("path")
    return p.parse_args(argv)


def _print_minari_hint(path: Path) -> None:
    """Tell how Minari's tools find a dataset written outside their datasets folder."""
    root = Path(*path.parts[:-3])
    ds_id = "/".join(path.parts[-3:])
    if root != minari_root():
        print(f"Minari's tools look in {minari_root()}; to use this dataset with them run\n"
              f"    export MINARI_DATASETS_PATH={root}\n"
              f"then `minari list local` or minari.load_dataset({ds_id!r}); "
              f"lfd_envs.datasets.load({str(path)!r}) works as it is.")
    else:
        print(f"`minari list local` and minari.load_dataset({ds_id!r}) find it.")


def main(argv: list[str] | None = None) -> int:
    """The command line; a bad argument prints one ``error:`` line and returns 2."""
    args = _parse(argv)
    try:
        _run(args)
    except (ValueError, TypeError, FileExistsError, FileNotFoundError, OSError, gym.error.Error) as exc:
        print(f"python -m lfd_envs.datasets {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _run(args: argparse.Namespace) -> None:
    if args.command == "collect":
        kwargs = {k: v for k, v in {"num_pickers": args.num_pickers, "action_mode": args.action_mode,
                                    "obs_mode": args.obs_mode, "resolution": args.resolution}.items() if v is not None}
        path = collect(args.env, args.episodes, args.out, env_kwargs=kwargs, policy=args.policy,
                       seed=args.seed, split=args.split, name=args.name, policy_kwargs=args.policy_kwargs,
                       overwrite=args.overwrite)
        ds = load(path)
        finals = final_performances(ds.iterate_episodes())
        print(f"wrote {path}: {ds.total_episodes} episodes, {ds.total_steps} steps, "
              f"mean final p̂ {np.mean(finals):.3f}")
        _print_minari_hint(path)
    else:
        ds = load(args.path)
        finals = final_performances(ds.iterate_episodes())
        print(json.dumps({**dataset_config(ds), "episodes": ds.total_episodes, "steps": ds.total_steps,
                          "mean_final_normalized_performance": float(np.mean(finals))}, indent=2))


if __name__ == "__main__":
    sys.exit(main())
