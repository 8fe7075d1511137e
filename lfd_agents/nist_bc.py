"""Multi-task visual behaviour cloning for ``NistBoardInsert-v0`` (RT-1-style, thesis ch. 6, on CPU).

Architecture (:class:`RT1Policy`), a scaled-down RT-1 with the thesis' changes:

* **instruction**: a fixed, download-free text embedding: the instruction's words and word
  bigrams are hashed (CRC32) into ``instruction_buckets`` and averaged by a learned
  ``EmbeddingBag`` (bigrams tell "small peg in large hole" from "large peg in small hole");
* **images**: each camera image of each history step goes through a small EfficientNet-like
  encoder (a stride-2 stem, then depthwise-separable conv blocks) whose every block is
  FiLM-conditioned on the instruction embedding, as in RT-1; the final feature map is pooled
  to ``tokens_hw`` tokens per image;
* **two cameras** (workspace + wrist) and a **short history** (``history`` = 2 by default,
  6 for the ablation): the image tokens of all steps and cameras, plus one instruction token,
  with learned position embeddings, go through a small Transformer encoder;
* **discretised actions**: the pooled output gives ``3 × n_bins`` logits, one categorical per
  axis, trained with cross-entropy (RT-1's action tokens). With the env's default 21 bins a
  bin is 0.3 mm of commanded motion in both action modes (continuous actions are mapped to
  bin centres).

Training data: a list of episodes (``{"observations": {cam: (T+1, H, W, 3), "instruction":
str}, "actions": (T, 3)}``), a Minari dataset from :func:`lfd_envs.datasets.collect`, or a
dataset folder; by default ``n_demos`` scripted demonstrations (with recovery) of ``train_tasks``
(the thesis' two training tasks, so ``"insert small peg in large hole"`` stays held out) are
collected in memory on first :meth:`NistBC.learn`.

API (SB3-like)::

    agent = NistBC(env, history=2, cameras=("workspace", "wrist"))
    agent.learn(total_timesteps=2000)      # gradient steps (one mini-batch each); or epochs=...
    agent.reset()                          # at every episode start (or pass episode_start=True)
    action, _ = agent.predict(obs, deterministic=True)
    agent.save("bc.pt"); agent = NistBC.load("bc.pt", env)

Images are resized to ``policy_image_size`` (default: the env's size) before the encoder; the
harness factories below use at most 64×80 to keep CPU training affordable.

Ablations from the benchmark harness: ``--agent lfd_agents.nist_bc:nist_bc`` (history 2, two
cameras), ``nist_bc_h6`` (history 6) and ``nist_bc_1cam`` (workspace camera only).
"""

from __future__ import annotations

import zlib
from collections import deque
from pathlib import Path
from typing import Any, Iterable, Sequence

import gymnasium as gym
import numpy as np
import torch as th
import torch.nn.functional as F
from torch import nn
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from lfd_agents.augment import random_shift
from lfd_agents.threads import torch_threads
from lfd_envs.core.rollout import episode_steps, play_episode

DEFAULT_CAMERAS = ("workspace", "wrist")


# ---------------------------------------------------------------------- instruction features
def instruction_ids(text: str, buckets: int) -> list[int]:
    """Hashed word and word-bigram ids of an instruction (a fixed, learned-free tokenizer)."""
    words = str(text).lower().split()
    grams = words + [f"{a}_{b}" for a, b in zip(words, words[1:])]
    if not grams:
        grams = ["<empty>"]
    return [zlib.crc32(g.encode()) % buckets for g in grams]


# ---------------------------------------------------------------------- network
class FiLM(nn.Module):
    """Feature-wise affine modulation ``x · (1 + γ(e)) + β(e)`` from a conditioning vector ``e``."""

    def __init__(self, cond_dim: int, channels: int):
        super().__init__()
        self.proj = nn.Linear(cond_dim, 2 * channels)
        nn.init.zeros_(self.proj.weight)
        nn.init.zeros_(self.proj.bias)

    def forward(self, x: th.Tensor, cond: th.Tensor) -> th.Tensor:
        gamma, beta = self.proj(cond).chunk(2, dim=-1)
        return x * (1.0 + gamma[:, :, None, None]) + beta[:, :, None, None]


class SeparableFiLMBlock(nn.Module):
    """Depthwise 3×3 + pointwise 1×1 conv, GroupNorm, FiLM, SiLU (an MBConv-lite block)."""

    def __init__(self, c_in: int, c_out: int, stride: int, cond_dim: int):
        super().__init__()
        self.depthwise = nn.Conv2d(c_in, c_in, 3, stride=stride, padding=1, groups=c_in, bias=False)
        self.pointwise = nn.Conv2d(c_in, c_out, 1, bias=False)
        self.norm = nn.GroupNorm(min(8, c_out), c_out)
        self.film = FiLM(cond_dim, c_out)
        self.residual = stride == 1 and c_in == c_out

    def forward(self, x: th.Tensor, cond: th.Tensor) -> th.Tensor:
        y = F.silu(self.film(self.norm(self.pointwise(self.depthwise(x))), cond))
        return x + y if self.residual else y


class SpatialSoftmax(nn.Module):
    """Expected image coordinates of ``k`` learned feature maps (visuomotor keypoints)."""

    def __init__(self, channels: int, k: int):
        super().__init__()
        self.proj = nn.Conv2d(channels, k, 1)

    def forward(self, x: th.Tensor) -> th.Tensor:
        n, _, h, w = x.shape
        attn = self.proj(x).flatten(2).softmax(dim=-1).view(n, -1, h, w)
        ys = th.linspace(-1.0, 1.0, h, device=x.device)
        xs = th.linspace(-1.0, 1.0, w, device=x.device)
        return th.cat([(attn.sum(3) * ys).sum(-1), (attn.sum(2) * xs).sum(-1)], dim=1)  # (N, 2k)


class ImageTokenizer(nn.Module):
    """FiLM-conditioned conv encoder: image (N, 3, H, W) in [0, 1] → tokens (N, k, d).

    A stride-2 stem and stride-2 separable blocks bring the feature map down to about 8 rows,
    then two stride-1 blocks; the map is average-pooled to ``tokens_hw`` tokens and summarised
    by one more token of ``keypoints`` spatial-softmax coordinates (precise positions of the
    peg and holes are what insertion needs).
    """

    def __init__(self, image_hw: tuple[int, int], cond_dim: int, d_model: int, tokens_hw: tuple[int, int] = (2, 2),
                 keypoints: int = 16):
        super().__init__()
        widths = (16, 32, 64)
        # CoordConv: two extra input channels with the pixel coordinates make image positions explicit
        self.stem = nn.Sequential(nn.Conv2d(5, widths[0], 3, stride=2, padding=1), nn.GroupNorm(4, widths[0]), nn.SiLU())
        downs = max(0, int(round(np.log2(max(1, image_hw[0] // 2) / 8))))
        strides = [2] * downs + [1, 1]
        blocks, c = [], widths[0]
        for i, stride in enumerate(strides):
            w = widths[min(i + 1, len(widths) - 1)]
            blocks.append(SeparableFiLMBlock(c, w, stride=stride, cond_dim=cond_dim))
            c = w
        self.blocks = nn.ModuleList(blocks)
        self.pool = nn.AdaptiveAvgPool2d(tokens_hw)
        self.out = nn.Linear(c, d_model)
        self.keypoints = SpatialSoftmax(c, keypoints)
        self.keypoint_token = nn.Linear(2 * keypoints, d_model)
        self.num_tokens = tokens_hw[0] * tokens_hw[1] + 1

    @staticmethod
    def _with_coordinates(images: th.Tensor) -> th.Tensor:
        n, _, h, w = images.shape
        ys = th.linspace(-1.0, 1.0, h, device=images.device).view(1, 1, h, 1).expand(n, 1, h, w)
        xs = th.linspace(-1.0, 1.0, w, device=images.device).view(1, 1, 1, w).expand(n, 1, h, w)
        return th.cat([images, ys, xs], dim=1)

    def forward(self, images: th.Tensor, cond: th.Tensor) -> th.Tensor:
        x = self.stem(self._with_coordinates(images))
        for block in self.blocks:
            x = block(x, cond)
        pooled = self.out(self.pool(x).flatten(2).transpose(1, 2))  # (N, hw, d)
        keys = self.keypoint_token(self.keypoints(x))[:, None, :]  # (N, 1, d)
        return th.cat([pooled, keys], dim=1)


class RT1Policy(nn.Module):
    """Instruction + image history → per-axis action-bin logits (see the module docstring)."""

    def __init__(self, n_cameras: int, history: int, n_bins: int, image_hw: tuple[int, int] = (32, 40),
                 d_model: int = 64, n_layers: int = 2,
                 n_heads: int = 4, instruction_buckets: int = 512, instruction_dim: int = 32,
                 tokens_hw: tuple[int, int] = (2, 2)):
        super().__init__()
        self.n_cameras, self.history, self.n_bins = n_cameras, history, n_bins
        self.instruction = nn.EmbeddingBag(instruction_buckets, instruction_dim, mode="mean")
        self.tokenizer = ImageTokenizer(image_hw, instruction_dim, d_model, tokens_hw=tokens_hw)
        n_tokens = history * n_cameras * self.tokenizer.num_tokens + 1
        self.instruction_token = nn.Linear(instruction_dim, d_model)
        self.position = nn.Parameter(th.zeros(1, n_tokens, d_model))
        nn.init.normal_(self.position, std=0.02)
        layer = nn.TransformerEncoderLayer(d_model, n_heads, dim_feedforward=2 * d_model, dropout=0.0,
                                           batch_first=True, norm_first=True)
        self.transformer = nn.TransformerEncoder(layer, n_layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(d_model)
        self.head = nn.Linear(d_model, 3 * n_bins)

    def forward(self, images: th.Tensor, instr_ids: th.Tensor, instr_offsets: th.Tensor) -> th.Tensor:
        """``images``: (B, history, cameras, 3, H, W) float in [0, 1] → logits (B, 3, n_bins)."""
        b, h, c = images.shape[:3]
        emb = self.instruction(instr_ids, instr_offsets)  # (B, E)
        cond = emb[:, None, None, :].expand(b, h, c, emb.shape[-1]).reshape(b * h * c, -1)
        tokens = self.tokenizer(images.flatten(0, 2), cond)  # (B·h·c, k, d)
        tokens = tokens.reshape(b, h * c * tokens.shape[1], -1)
        tokens = th.cat([self.instruction_token(emb)[:, None, :], tokens], dim=1) + self.position
        out = self.norm(self.transformer(tokens).mean(dim=1))
        return self.head(out).view(b, 3, self.n_bins)


# ---------------------------------------------------------------------- demonstrations
def _env_config(env: gym.Env) -> dict[str, Any]:
    """Constructor arguments of a NistBoardInsert env that the demonstrations must share."""
    e = env.unwrapped
    return {"fit": e.fit, "action_mode": e.action_mode, "image_size": tuple(e.image_size),
            "cameras": tuple(e.cameras), "action_repeat": e.action_repeat, "max_delta": e.max_delta,
            "horizon": e.horizon}


def collect_demonstrations(env_kwargs: dict[str, Any], episodes: int, seed: int = 0,
                           expert_kwargs: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """Roll out the scripted expert (with recovery) in memory; returns successful episodes."""
    from lfd_envs.experts import make_expert
    from lfd_envs.mujoco.nist import NistBoardInsertEnv

    env = NistBoardInsertEnv(**{**env_kwargs, "obs_mode": "image"})
    expert = make_expert(env, **(expert_kwargs or {}))
    out: list[dict[str, Any]] = []
    attempt = 0
    while len(out) < int(episodes) and attempt < 3 * int(episodes):
        obs, _ = env.reset(seed=seed + attempt)
        attempt += 1
        expert.reset()
        observations, actions, info = [obs], [], {}
        for step in episode_steps(env, expert, obs):
            observations.append(step.obs)
            actions.append(np.asarray(step.action))
            info = step.info
        if info.get("is_success", False):
            cams = {c: np.stack([o[c] for o in observations]) for c in env.cameras}
            out.append({"observations": {**cams, "instruction": observations[0]["instruction"]},
                        "actions": np.stack(actions)})
    env.close()
    return out


def _image_array(frames: Any) -> np.ndarray:
    """Frames as uint8 (T, H, W, 3); decodes the JPEG bytes Minari returns for images < 32 px."""
    arr = np.asarray(frames)
    if arr.dtype != object and arr.ndim == 4:
        return arr
    import io

    from PIL import Image

    return np.stack([np.asarray(Image.open(io.BytesIO(np.asarray(f, np.uint8).tobytes())).convert("RGB"))
                     for f in frames])


def _as_episodes(demonstrations: Any) -> list[dict[str, Any]]:
    """Normalise a list of episodes / a Minari dataset / a dataset folder to episode dicts."""
    if isinstance(demonstrations, (str, Path)):
        from lfd_envs import datasets

        demonstrations = datasets.load(demonstrations)
    if hasattr(demonstrations, "iterate_episodes"):
        episodes = []
        for ep in demonstrations.iterate_episodes():
            obs = ep.observations
            instr = obs["instruction"]
            instr = instr[0] if not isinstance(instr, str) else instr
            instr = instr.decode() if isinstance(instr, bytes) else str(instr)
            cams = {k: _image_array(v) for k, v in obs.items() if k in DEFAULT_CAMERAS}
            episodes.append({"observations": {**cams, "instruction": instr}, "actions": np.asarray(ep.actions)})
        return episodes
    episodes = list(demonstrations)
    if not episodes:
        raise ValueError("demonstrations must contain at least one episode")
    return episodes


# ---------------------------------------------------------------------- agent
class NistBC:
    """Instruction-conditioned visual BC with an image history (RT-1-style); SB3-like API.

    Args:
        env: a ``NistBoardInsert-v0`` env with image observations (wrappers allowed).
        demonstrations: episodes, a Minari dataset or a dataset folder; ``None`` collects
            ``n_demos`` expert episodes of ``train_tasks`` on first :meth:`learn`.
        history: observation steps per decision (the thesis' best: 2; ablation: 6).
        cameras: cameras the policy sees (``("workspace", "wrist")`` or one of them).
        n_demos: demonstrations to collect when ``demonstrations`` is None.
        policy_image_size: ``(H, W)`` the images are resized to (area averaging) before the
            encoder; None = the env's ``image_size``. Training cost grows with the pixel count.
        train_tasks: instructions of the collected demonstrations (default: the thesis' two).
        batch_size, learning_rate: optimiser settings (AdamW).
        augment: random shifts (±2 px) and brightness jitter of training images.
        lr_decay_steps: when set, the learning rate follows a cosine from ``learning_rate`` to 0
            over this many gradient steps (counted across :meth:`learn` calls) and stays at 0
            after; None keeps it constant.
        ema_decay: when set, an exponential moving average of the weights (this decay per
            gradient step) is kept and used for acting and saved; None acts with the raw weights.
        d_model, n_layers: Transformer width and depth.
        expert_kwargs: passed to the expert (e.g. ``recovery_prob``).
        seed: seeds torch, the batch sampler and demonstration collection.
        device: torch device (CPU by default).
        num_threads: torch threads while training/acting (1 by default: this small network is
            fastest single-threaded, and multi-threading collapses on a busy CPU); None = torch's.
    """

    def __init__(self, env: gym.Env, demonstrations: Any = None, *, history: int = 2,
                 cameras: Sequence[str] = DEFAULT_CAMERAS, n_demos: int = 40,
                 policy_image_size: tuple[int, int] | None = None,
                 train_tasks: Sequence[str] | None = None, batch_size: int = 32, learning_rate: float = 1e-3,
                 augment: bool = True, d_model: int = 64, n_layers: int = 2,
                 lr_decay_steps: int | None = None, ema_decay: float | None = None,
                 expert_kwargs: dict[str, Any] | None = None, seed: int = 0, device: str = "cpu",
                 num_threads: int | None = 1, verbose: int = 0) -> None:
        from lfd_envs.mujoco.nist import TRAIN_TASKS

        e = env.unwrapped
        cams = (cameras,) if isinstance(cameras, str) else tuple(cameras)
        if not cams or any(c not in e.cameras for c in cams):
            raise ValueError(f"cameras must be a non-empty subset of the env's cameras {e.cameras}, got {cameras!r}")
        if int(history) < 1:
            raise ValueError(f"history must be >= 1, got {history}")
        if e.obs_mode == "state":
            raise ValueError("NistBC needs image observations (obs_mode 'image' or 'state+image')")
        if lr_decay_steps is not None and int(lr_decay_steps) < 1:
            raise ValueError(f"lr_decay_steps must be >= 1 or None, got {lr_decay_steps}")
        if ema_decay is not None and not 0.0 < float(ema_decay) < 1.0:
            raise ValueError(f"ema_decay must be in (0, 1) or None, got {ema_decay}")
        self.env = env
        self.config = {
            "history": int(history), "cameras": cams, "n_demos": int(n_demos),
            "train_tasks": tuple(train_tasks or TRAIN_TASKS), "batch_size": int(batch_size),
            "learning_rate": float(learning_rate), "augment": bool(augment), "d_model": int(d_model),
            "n_layers": int(n_layers), "seed": int(seed),
            "lr_decay_steps": None if lr_decay_steps is None else int(lr_decay_steps),
            "ema_decay": None if ema_decay is None else float(ema_decay), "expert_kwargs": dict(expert_kwargs or {}),
            "n_bins": int(e.num_bins), "action_mode": e.action_mode, "image_size": tuple(e.image_size),
            "policy_image_size": tuple(int(v) for v in (policy_image_size or e.image_size)),
            "instruction_buckets": 512,
        }
        self.device = th.device(device)
        self.num_threads = num_threads
        self.verbose = int(verbose)
        th.manual_seed(int(seed))
        self.policy = RT1Policy(len(cams), int(history), e.num_bins, image_hw=self.config["policy_image_size"],
                                d_model=int(d_model),
                                n_layers=int(n_layers), instruction_buckets=512).to(self.device)
        self.optimizer = th.optim.AdamW(self.policy.parameters(), lr=float(learning_rate), weight_decay=1e-4)
        self.ema = None
        if ema_decay is not None:
            self.ema = AveragedModel(self.policy, multi_avg_fn=get_ema_multi_avg_fn(float(ema_decay)),
                                     use_buffers=True)
        self._rng = np.random.default_rng(int(seed))
        self._demonstrations = demonstrations
        self._data: dict[str, Any] | None = None
        self.num_timesteps = 0
        self._history: deque = deque(maxlen=int(history))

    # ------------------------------------------------------------------ data
    def _resize(self, frames: np.ndarray) -> np.ndarray:
        """uint8 (..., H, W, 3) frames at ``policy_image_size``."""
        h, w = self.config["policy_image_size"]
        if frames.shape[-3:-1] == (h, w):
            return frames
        import cv2

        flat = frames.reshape(-1, *frames.shape[-3:])
        out = np.stack([cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA) for f in flat])
        return out.reshape(*frames.shape[:-3], h, w, 3)

    def _actions_to_bins(self, actions: np.ndarray) -> np.ndarray:
        n = self.config["n_bins"]
        if self.config["action_mode"] == "tokens":
            return np.clip(np.round(actions), 0, n - 1).astype(np.int64)
        return np.clip(np.round((np.asarray(actions, np.float64) + 1.0) * 0.5 * (n - 1)), 0, n - 1).astype(np.int64)

    def _bins_to_actions(self, bins: np.ndarray) -> np.ndarray:
        if self.config["action_mode"] == "tokens":
            return bins.astype(np.int64)
        return (bins / (self.config["n_bins"] - 1) * 2.0 - 1.0).astype(np.float32)

    def _prepare_data(self) -> dict[str, Any]:
        demos = self._demonstrations
        if demos is None:
            kwargs = {**_env_config(self.env), "instruction": self.config["train_tasks"]}
            demos = collect_demonstrations(kwargs, self.config["n_demos"], seed=self.config["seed"] * 1_000_003,
                                           expert_kwargs=self.config["expert_kwargs"])
        episodes = _as_episodes(demos)
        h, cams = self.config["history"], self.config["cameras"]
        frames = {c: [] for c in cams}
        hist_idx, labels, instr = [], [], []
        offset = 0
        for ep in episodes:
            obs, actions = ep["observations"], np.asarray(ep["actions"])
            missing = [c for c in cams if c not in obs]
            if missing:
                raise ValueError(f"demonstrations lack camera images {missing}; they have {sorted(obs)}")
            t_len = len(actions)
            for c in cams:
                frames[c].append(self._resize(np.asarray(obs[c])[: t_len + 1]))
            ids = instruction_ids(obs["instruction"], self.config["instruction_buckets"])
            for t in range(t_len):
                hist_idx.append([offset + max(0, t - h + 1 + j) for j in range(h)])
                instr.append(ids)
            labels.append(self._actions_to_bins(actions.reshape(t_len, 3)))
            offset += t_len + 1
        if not labels:
            raise ValueError("the demonstrations hold no transitions")
        data = {
            "frames": {c: th.from_numpy(np.concatenate(frames[c])) for c in cams},  # uint8 (N, H, W, 3)
            "history": np.asarray(hist_idx, dtype=np.int64),
            "labels": th.from_numpy(np.concatenate(labels)),
            "instructions": instr,
            "episodes": len(episodes),
        }
        return data

    def _instruction_batch(self, instructions: list[list[int]]) -> tuple[th.Tensor, th.Tensor]:
        lengths = [len(i) for i in instructions]
        flat = th.tensor([x for i in instructions for x in i], dtype=th.long, device=self.device)
        offsets = th.tensor(np.concatenate([[0], np.cumsum(lengths)[:-1]]), dtype=th.long, device=self.device)
        return flat, offsets

    def _image_batch(self, per_camera: list[th.Tensor], augment: bool) -> th.Tensor:
        """Stack uint8 (B, h, H, W, 3) per camera → float (B, h, cams, 3, H, W) in [0, 1]."""
        x = th.stack(per_camera, dim=2).to(self.device).permute(0, 1, 2, 5, 3, 4).float() / 255.0
        if augment:
            b, h, c = x.shape[:3]
            flat = random_shift(x.flatten(0, 2), pad=2)
            gain = th.empty(b * h * c, 1, 1, 1, device=self.device).uniform_(0.8, 1.2)
            x = (flat * gain).clamp(0.0, 1.0).view_as(x)
        return x

    # ------------------------------------------------------------------ training
    def learn(self, total_timesteps: int | None = None, epochs: float | None = None,
              reset_num_timesteps: bool = True, progress_bar: bool = False, **_: Any) -> "NistBC":
        """Train on the demonstrations.

        Args:
            total_timesteps: gradient steps (one mini-batch each) for this call.
            epochs: alternatively, passes over the demonstration transitions.
        """
        with torch_threads(self.num_threads):
            return self._learn(total_timesteps, epochs)

    def _learn(self, total_timesteps: int | None, epochs: float | None) -> "NistBC":
        if self._data is None:
            self._data = self._prepare_data()
        data = self._data
        n = len(data["labels"])
        bs = self.config["batch_size"]
        if total_timesteps is None:
            if epochs is None:
                raise ValueError("give total_timesteps (gradient steps) or epochs")
            total_timesteps = int(np.ceil(float(epochs) * n / bs))
        self.policy.train()
        for step in range(int(total_timesteps)):
            self._set_learning_rate()
            idx = self._rng.integers(n, size=bs)
            hist = th.from_numpy(data["history"][idx])
            images = self._image_batch([data["frames"][c][hist] for c in self.config["cameras"]],
                                       augment=self.config["augment"])
            ids, offsets = self._instruction_batch([data["instructions"][i] for i in idx])
            logits = self.policy(images, ids, offsets)
            loss = F.cross_entropy(logits.reshape(-1, self.config["n_bins"]), data["labels"][idx].reshape(-1).to(self.device))
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            if self.ema is not None:
                self.ema.update_parameters(self.policy)
            self.num_timesteps += 1
            if self.verbose and (step % 100 == 0 or step == total_timesteps - 1):
                print(f"NistBC step {self.num_timesteps}: loss {loss.item():.4f}")
        self.last_loss = float(loss.item()) if int(total_timesteps) > 0 else float("nan")
        return self

    def _set_learning_rate(self) -> None:
        """Cosine decay of the learning rate over ``lr_decay_steps`` gradient steps (if set)."""
        horizon = self.config["lr_decay_steps"]
        if horizon is None:
            return
        progress = min(self.num_timesteps / horizon, 1.0)
        lr = 0.5 * self.config["learning_rate"] * (1.0 + np.cos(np.pi * progress))
        for group in self.optimizer.param_groups:
            group["lr"] = lr

    @property
    def acting_policy(self) -> nn.Module:
        """The network used to act: the weight average when ``ema_decay`` is set, else the policy."""
        return self.policy if self.ema is None else self.ema.module

    # ------------------------------------------------------------------ acting
    def reset(self) -> None:
        """Forget the observation history (call at every episode start)."""
        self._history.clear()

    def predict(self, observation: dict[str, Any], state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """Action for one observation dict (the policy keeps the last ``history`` observations)."""
        if not isinstance(observation, dict) or "instruction" not in observation:
            raise ValueError("NistBC.predict expects one NistBoardInsert observation dict with 'instruction'")
        if episode_start is not None and bool(np.any(episode_start)):
            self.reset()
        frame = {c: th.from_numpy(np.ascontiguousarray(self._resize(np.asarray(observation[c]))))
                 for c in self.config["cameras"]}
        if not self._history:
            self._history.extend([frame] * self.config["history"])
        else:
            self._history.append(frame)
        per_camera = [th.stack([f[c] for f in self._history])[None] for c in self.config["cameras"]]
        instr = observation["instruction"]
        instr = instr[0] if not isinstance(instr, str) else instr
        ids, offsets = self._instruction_batch([instruction_ids(instr, self.config["instruction_buckets"])])
        policy = self.acting_policy
        policy.eval()
        with th.no_grad(), torch_threads(self.num_threads):
            logits = policy(self._image_batch(per_camera, augment=False), ids, offsets)[0]
        if deterministic:
            bins = logits.argmax(-1)
        else:
            bins = th.distributions.Categorical(logits=logits).sample()
        return self._bins_to_actions(bins.cpu().numpy()), None

    # ------------------------------------------------------------------ persistence
    def save(self, path: str | Path) -> None:
        """Save the network, optimiser and config (not the demonstrations)."""
        th.save({"config": self.config, "policy": self.policy.state_dict(),
                 "optimizer": self.optimizer.state_dict(), "num_timesteps": self.num_timesteps,
                 "ema": None if self.ema is None else self.ema.state_dict(),
                 "num_threads": self.num_threads}, str(path))

    @classmethod
    def load(cls, path: str | Path, env: gym.Env, demonstrations: Any = None, device: str = "cpu") -> "NistBC":
        """Load a saved agent for ``env`` (same action mode and bins; images are resized as saved)."""
        ckpt = th.load(str(path), map_location=device, weights_only=False)
        cfg = ckpt["config"]
        e = env.unwrapped
        if e.action_mode != cfg["action_mode"] or e.num_bins != cfg["n_bins"]:
            raise ValueError(f"env (action_mode={e.action_mode!r}, {e.num_bins} bins) does not match the saved "
                             f"agent (action_mode={cfg['action_mode']!r}, {cfg['n_bins']} bins)")
        agent = cls(env, demonstrations, history=cfg["history"], cameras=cfg["cameras"], n_demos=cfg["n_demos"],
                    policy_image_size=cfg.get("policy_image_size"),
                    train_tasks=cfg["train_tasks"], batch_size=cfg["batch_size"], learning_rate=cfg["learning_rate"],
                    augment=cfg["augment"], d_model=cfg["d_model"], n_layers=cfg["n_layers"],
                    lr_decay_steps=cfg.get("lr_decay_steps"), ema_decay=cfg.get("ema_decay"),
                    expert_kwargs=cfg["expert_kwargs"], seed=cfg["seed"], device=device)
        agent.num_threads = ckpt.get("num_threads", agent.num_threads)
        agent.policy.load_state_dict(ckpt["policy"])
        agent.optimizer.load_state_dict(ckpt["optimizer"])
        if agent.ema is not None and ckpt.get("ema") is not None:
            agent.ema.load_state_dict(ckpt["ema"])
        agent.num_timesteps = int(ckpt["num_timesteps"])
        return agent

    @classmethod
    def for_benchmark(cls, env: gym.Env, seed: int = 0, **kwargs: Any) -> "NistBC":
        """Factory used by the benchmark harness (``total_timesteps`` = gradient steps)."""
        return cls(env, seed=seed, **kwargs)


# ---------------------------------------------------------------------- evaluation and factories
def evaluate(agent: Any, env: gym.Env, episodes: int, seed: int = 0, split: str = "eval") -> dict[str, float]:
    """Success rate, mean final p̂ and mean final lateral distance (m) of the peg tip to the hole
    axis of ``agent`` on variants ``0 .. episodes-1`` of ``split``."""
    successes, finals, lateral = [], [], []
    for k in range(int(episodes)):
        info = play_episode(env, agent, seed=seed + k, options={"split": split, "variant": k})
        successes.append(bool(info.get("is_success", False)))
        finals.append(float(info["normalized_performance"]))
        e = env.unwrapped
        lateral.append(float(np.linalg.norm(e.tip_position[:2] - e.hole_top[:2])))
    return {"success_rate": float(np.mean(successes)), "mean_normalized_performance": float(np.mean(finals)),
            "mean_lateral_error": float(np.mean(lateral))}


BENCHMARK_IMAGE_SIZE = (64, 80)  #: policy input of the harness factories (CPU budget)


def _factory_kwargs(env: gym.Env, kwargs: dict[str, Any], **defaults: Any) -> dict[str, Any]:
    h, w = env.unwrapped.image_size
    size = BENCHMARK_IMAGE_SIZE if h * w > BENCHMARK_IMAGE_SIZE[0] * BENCHMARK_IMAGE_SIZE[1] else None
    return {"policy_image_size": size, **defaults, **kwargs}


def nist_bc(env: gym.Env, seed: int = 0, **kwargs: Any) -> NistBC:
    """The thesis' design: history 2, workspace + wrist cameras (images ≤ 64×80 for the CPU)."""
    return NistBC(env, seed=seed, **_factory_kwargs(env, kwargs, history=2, cameras=DEFAULT_CAMERAS))


def nist_bc_h6(env: gym.Env, seed: int = 0, **kwargs: Any) -> NistBC:
    """Ablation: history 6 (two cameras)."""
    return NistBC(env, seed=seed, **_factory_kwargs(env, kwargs, history=6, cameras=DEFAULT_CAMERAS))


def nist_bc_1cam(env: gym.Env, seed: int = 0, **kwargs: Any) -> NistBC:
    """Ablation: the workspace camera only (RT-1's single camera), history 2."""
    return NistBC(env, seed=seed, **_factory_kwargs(env, kwargs, history=2, cameras=("workspace",)))


nist_bc_h2 = nist_bc

__all__ = ["NistBC", "RT1Policy", "collect_demonstrations", "evaluate", "instruction_ids",
           "nist_bc", "nist_bc_h2", "nist_bc_h6", "nist_bc_1cam"]
