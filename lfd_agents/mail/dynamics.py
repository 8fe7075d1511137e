"""Learned particle dynamics for MAIL: 1D-CNN over particles + LSTM over steps.

The model maps the particle positions ``x_t`` (K, 3) and a pick-and-place action ``a_t`` to
per-particle displacements ``Δx_t`` so that ``x_{t+1} = x_t + Δx_t`` (MAIL's target, reference
§3.4). Architecture (after MAIL's ``CNNForwardDynamicsLSTM``, scaled to a CPU):

* **normalisation**: particle positions are mapped into the task's *workspace box* exactly like
  the normalised pick-and-place actions (``[-1, 1]`` per axis), so positions and actions live in
  one frame; the displacement target is additionally divided by its per-axis standard deviation
  over the training data (stored with the model);
* **action encoding**: besides the raw action (fed to the LSTM as in MAIL), every particle gets
  its offset to each picker's pick point and each picker's carry vector ``place − pick`` as input
  channels, so "particles near the pick point follow the carry" is a local rule the network can
  learn from a few hundred transitions (a global encoding of the action needs far more data);
* per step, a dilated 1D convolution stack over the particle index (particles in grid / box
  order, so array neighbours are object neighbours) gives per-particle features; their mean and
  max over particles plus the action enter an LSTM that carries a hidden state across steps;
* a fully connected head applied to every particle (shared weights) on [local feature, LSTM
  state, inputs]: ``Linear → LeakyReLU → Linear → LayerNorm → tanh → Linear`` → displacement.

Particles are sub-sampled to at most ``num_points`` fixed indices (:func:`subsample_indices`:
a regular sub-grid of a square cloth, else evenly spaced indices) so the model size and cost
do not grow with the simulator resolution; :meth:`LearnedDynamics.predict_all` moves every
particle with its nearest sub-sampled particle.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import torch
from torch import nn

from lfd_agents.threads import torch_threads


@dataclass
class DynamicsConfig:
    """Sizes and training settings of :class:`ParticleDynamicsModel` (defaults fit a 2-core CPU)."""

    num_points: int = 256  #: particles kept (see :func:`subsample_indices`)
    num_pickers: int = 1  #: pickers of the (student) action: action_dim = 6 * num_pickers
    conv_channels: int = 32
    conv_layers: int = 4  #: kernel 3, dilations 1, 2, 4, 8, ...
    lstm_hidden: int = 64
    head_hidden: int = 64
    learning_rate: float = 1e-3
    batch_size: int = 32
    #: torch intra-op threads while training/predicting (1 is fastest for these small tensors
    #: on a shared CPU: more threads oversubscribe and run ~20x slower); 0 keeps torch's setting
    num_threads: int = 1
    #: carry the LSTM state across the steps of a rollout. MAIL trains on length-1 sequences
    #: (as :meth:`LearnedDynamics.fit` does), so a carried state is one the model never saw in
    #: training; by default every step starts from the zero state (ThreeBoxes 3→1, 4 demos:
    #: mean p̂ 0.55 vs 0.53 carried, i.e. no worse)
    carry_hidden: bool = False
    #: workspace box (metres) of the normalised actions; positions are normalised with it too
    workspace_low: tuple[float, float, float] = (-1.0, -1.0, -1.0)
    workspace_high: tuple[float, float, float] = (1.0, 1.0, 1.0)

    @property
    def action_dim(self) -> int:
        return 6 * self.num_pickers

    @property
    def input_channels(self) -> int:
        return 3 + 6 * self.num_pickers


class ParticleDynamicsModel(nn.Module):
    """CNN-LSTM forward model predicting normalised per-particle displacements."""

    def __init__(self, config: DynamicsConfig):
        super().__init__()
        self.config = config
        c, cin = config.conv_channels, config.input_channels
        layers: list[nn.Module] = []
        for i in range(config.conv_layers):
            d = 2 ** i
            layers += [nn.Conv1d(cin if i == 0 else c, c, 3, padding=d, dilation=d), nn.LeakyReLU()]
        self.encoder = nn.Sequential(*layers)
        self.lstm = nn.LSTM(2 * c + config.action_dim, config.lstm_hidden, batch_first=True)
        hid = config.head_hidden
        self.head = nn.Sequential(
            nn.Linear(c + config.lstm_hidden + cin, hid), nn.LeakyReLU(), nn.Linear(hid, hid),
            nn.LayerNorm(hid), nn.Tanh(), nn.Linear(hid, 3))
        # per-axis std of the normalised displacement (set from the data by LearnedDynamics.fit)
        self.register_buffer("disp_scale", torch.ones(3))

    def features(self, points: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        """Per-particle inputs ``(B, K, 3 + 6m)``: position, offset to each pick, each carry vector."""
        b, k, _ = points.shape
        m = self.config.num_pickers
        a = actions.reshape(b, 2, m, 3)
        pick, place = a[:, 0], a[:, 1]  # (B, m, 3)
        rel = points[:, :, None, :] - pick[:, None]  # (B, K, m, 3)
        carry = (place - pick)[:, None].expand(b, k, m, 3)
        return torch.cat([points, rel.reshape(b, k, 3 * m), carry.reshape(b, k, 3 * m)], dim=-1)

    def forward(self, points: torch.Tensor, actions: torch.Tensor,
                hidden: tuple[torch.Tensor, torch.Tensor] | None = None):
        """One or more steps.

        Args:
            points: (B, T, K, 3) normalised particle positions at each step's start.
            actions: (B, T, action_dim) normalised actions.
        Returns:
            normalised displacements (B, T, K, 3) and the LSTM hidden state.
        """
        b, t, k, _ = points.shape
        inp = self.features(points.reshape(b * t, k, 3), actions.reshape(b * t, -1))  # (BT, K, C)
        local = self.encoder(inp.transpose(1, 2))  # (BT, c, K)
        pooled = torch.cat([local.mean(dim=2), local.amax(dim=2)], dim=1).reshape(b, t, -1)
        h, hidden = self.lstm(torch.cat([pooled, actions], dim=-1), hidden)
        hb = h.reshape(b * t, 1, -1).expand(b * t, k, h.shape[-1])
        out = self.head(torch.cat([local.transpose(1, 2), hb, inp], dim=-1)) * self.disp_scale
        return out.reshape(b, t, k, 3), hidden


def subsample_indices(num_particles: int, num_points: int, grid: tuple[int, int] | None = None) -> np.ndarray:
    """Fixed particle indices for the model.

    With ``grid = (start, n)`` (a square ``n × n`` cloth whose particle ``(r, c)`` has index
    ``start + r·n + c``), a regular sub-grid of about ``num_points`` particles in row-major order
    (array neighbours stay cloth neighbours); otherwise ``num_points`` evenly spaced indices.
    """
    if num_points >= num_particles:
        return np.arange(num_particles, dtype=np.int64)
    if grid is not None:
        start, n = grid
        s = max(2, min(n, int(np.floor(np.sqrt(num_points)))))
        rows = np.unique(np.linspace(0, n - 1, s).round().astype(np.int64))
        return (start + rows[:, None] * n + rows[None, :]).reshape(-1)
    return np.unique(np.linspace(0, num_particles - 1, num_points).round().astype(np.int64))


def task_subsample_indices(task: Any, num_particles: int, num_points: int) -> np.ndarray:
    """:func:`subsample_indices` for a particle task (uses the cloth grid of cloth tasks)."""
    n = int(getattr(task, "resolution", 0) or 0)
    start = getattr(task, "cloth_start", None)
    grid = (int(start), n) if start is not None and n > 1 and start + n * n <= num_particles else None
    return subsample_indices(num_particles, num_points, grid)


class LearnedDynamics:
    """Train, save, load and roll out :class:`ParticleDynamicsModel`.

    Args:
        num_particles: particles per world in the simulator.
        config: model sizes, picker count and workspace box.
        seed: torch seed for initialisation and batching.
        indices: particle indices the model sees (default :func:`subsample_indices`).
    """

    def __init__(self, num_particles: int, config: DynamicsConfig | None = None, seed: int = 0,
                 device: str = "cpu", indices: np.ndarray | None = None):
        self.config = config or DynamicsConfig()
        self.num_particles = int(num_particles)
        if indices is None:
            indices = subsample_indices(self.num_particles, self.config.num_points)
        self.indices = np.asarray(indices, dtype=np.int64)
        if self.indices.min() < 0 or self.indices.max() >= self.num_particles:
            raise ValueError(f"indices must lie in [0, {self.num_particles})")
        lo = np.asarray(self.config.workspace_low, np.float64)
        hi = np.asarray(self.config.workspace_high, np.float64)
        if lo.shape != (3,) or hi.shape != (3,) or np.any(hi <= lo):
            raise ValueError(f"workspace_low < workspace_high (3 numbers each) required, got {lo}, {hi}")
        self._centre, self._half = (hi + lo) / 2, (hi - lo) / 2
        torch.manual_seed(seed)
        self.device = torch.device(device)
        self.model = ParticleDynamicsModel(self.config).to(self.device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=self.config.learning_rate)
        self.seed = seed
        self.history: list[float] = []
        self._fitted = False

    @classmethod
    def for_env(cls, env: Any, config: DynamicsConfig | None = None, seed: int = 0) -> "LearnedDynamics":
        """Model for a particle env in ``pick_place`` mode (workspace, pickers, sub-sampling from it)."""
        base = env.unwrapped
        ws = base.workspace
        cfg = DynamicsConfig(**{**asdict(config or DynamicsConfig()), "num_pickers": int(base.num_pickers),
                                "workspace_low": tuple(float(v) for v in ws.lo),
                                "workspace_high": tuple(float(v) for v in ws.hi)})
        n = int(np.asarray(base.particle_positions).shape[0])
        return cls(n, cfg, seed=seed, indices=task_subsample_indices(base.task, n, cfg.num_points))

    # ------------------------------------------------------------------ frames
    def normalise(self, points: np.ndarray) -> np.ndarray:
        """Metres → the normalised action frame of the workspace box."""
        return (np.asarray(points, np.float64) - self._centre) / self._half

    def _tensor(self, x: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(x, dtype=np.float32), device=self.device)

    def _check_actions(self, actions: np.ndarray) -> np.ndarray:
        actions = np.asarray(actions, dtype=np.float32)
        if actions.shape[-1] != self.config.action_dim:
            raise ValueError(f"actions must have {self.config.action_dim} numbers (6 per picker), "
                             f"got shape {actions.shape}")
        return np.clip(actions, -1.0, 1.0)

    # ------------------------------------------------------------------ training
    def fit(self, x: np.ndarray, actions: np.ndarray, x_next: np.ndarray, epochs: int = 50,
            progress: bool = False) -> list[float]:
        """Train on one-step transitions (MSE on normalised displacements).

        Args:
            x, x_next: (M, N, 3) positions (metres) of all particles before and after the action.
            actions: (M, 6·pickers) normalised actions.
            epochs: passes over the data.
        Returns:
            mean training loss per epoch.
        """
        x, x_next = np.asarray(x), np.asarray(x_next)
        if len(x) != len(actions) or len(x) != len(x_next):
            raise ValueError(f"x, actions, x_next must have the same length, got {len(x)}, {len(actions)}, {len(x_next)}")
        if x.shape[1:] != (self.num_particles, 3) or x_next.shape != x.shape:
            raise ValueError(f"x and x_next must have shape (M, {self.num_particles}, 3), got {x.shape}, {x_next.shape}")
        xs = self.normalise(x[:, self.indices])
        ds = self.normalise(x_next[:, self.indices]) - xs
        if not self._fitted:  # displacement scale from the first training set
            scale = np.maximum(ds.reshape(-1, 3).std(axis=0), 1e-3)
            self.model.disp_scale.copy_(self._tensor(scale))
            self._fitted = True
        scale = self.model.disp_scale
        xt, at = self._tensor(xs)[:, None], self._tensor(self._check_actions(actions))[:, None]
        dt = self._tensor(ds)[:, None] / scale
        gen = torch.Generator().manual_seed(self.seed + len(self.history))
        self.model.train()
        with torch_threads(self.config.num_threads):
            losses = self._epochs(xt, at, dt, int(epochs), gen, progress)
        self.history += losses
        return losses

    def _epochs(self, xt: torch.Tensor, at: torch.Tensor, dt: torch.Tensor, epochs: int,
                gen: torch.Generator, progress: bool) -> list[float]:
        from tqdm import trange

        scale, bs = self.model.disp_scale, self.config.batch_size
        losses = []
        for _ in trange(int(epochs), desc="dynamics", disable=not progress, leave=False):
            perm = torch.randperm(len(xt), generator=gen)
            total = 0.0
            for i in range(0, len(xt), bs):
                idx = perm[i:i + bs]
                pred, _ = self.model(xt[idx], at[idx])
                loss = torch.mean((pred / scale - dt[idx]) ** 2)
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                total += float(loss.detach()) * len(idx)
            losses.append(total / len(xt))
        return losses

    # ------------------------------------------------------------------ prediction
    @torch.no_grad()
    def rollout(self, x0: np.ndarray, action_seqs: np.ndarray) -> np.ndarray:
        """Predict sub-sampled particle positions after each action sequence.

        Args:
            x0: (N, 3) start positions (all particles, metres) or (B, N, 3) one per sequence.
            action_seqs: (B, H, action_dim) normalised actions.
        Returns:
            (B, K, 3) predicted final positions (metres) of the particles :attr:`indices`.
        """
        acts = self._tensor(self._check_actions(action_seqs))
        b, horizon, _ = acts.shape
        x0 = np.asarray(x0)
        start = x0[..., self.indices, :]
        pts = np.broadcast_to(self.normalise(start), (b, len(self.indices), 3))
        cur = self._tensor(pts)
        hidden = None
        self.model.eval()
        with torch_threads(self.config.num_threads):
            for t in range(horizon):
                disp, hidden = self.model(cur[:, None], acts[:, t:t + 1], hidden)
                cur = cur + disp[:, 0]
                if not self.config.carry_hidden:
                    hidden = None
        return cur.double().cpu().numpy() * self._half + self._centre

    def predict_all(self, x0: np.ndarray, action_seq: np.ndarray) -> np.ndarray:
        """Final positions of ALL particles for one sequence (nearest sub-sampled neighbour motion)."""
        x0 = np.asarray(x0, np.float64)
        sub_final = self.rollout(x0, np.asarray(action_seq)[None])[0]
        sub_start = x0[self.indices]
        d = np.linalg.norm(x0[:, None] - sub_start[None], axis=-1)
        return x0 + (sub_final - sub_start)[d.argmin(axis=1)]

    # ------------------------------------------------------------------ io
    def save(self, path: str | Path) -> None:
        torch.save({"config": asdict(self.config), "num_particles": self.num_particles, "seed": self.seed,
                    "indices": self.indices, "state_dict": self.model.state_dict(), "history": self.history},
                   str(path))

    @classmethod
    def load(cls, path: str | Path, device: str = "cpu") -> "LearnedDynamics":
        blob = torch.load(str(path), map_location=device, weights_only=False)
        cfg = blob["config"]
        cfg["workspace_low"], cfg["workspace_high"] = tuple(cfg["workspace_low"]), tuple(cfg["workspace_high"])
        obj = cls(blob["num_particles"], DynamicsConfig(**cfg), seed=blob["seed"], device=device,
                  indices=blob["indices"])
        obj.model.load_state_dict(blob["state_dict"])
        obj.history = list(blob["history"])
        obj._fitted = True
        return obj


def transitions_from_episodes(episodes: Iterable[dict[str, np.ndarray]], num_particles: int,
                              picker: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-step ``(x, a, x_next)`` arrays from episodes with ``particles`` observations.

    Each episode is a dict with ``observations`` (T+1, N+P, 3) and pick-and-place ``actions``
    (T, 6·P) in the env layout ``[pick_1..pick_P, place_1..place_P]``. With ``picker=None`` the
    whole action is used, else only the pick and place of that picker (6 numbers).
    """
    xs, acts, nxt = [], [], []
    for ep in episodes:
        obs = np.asarray(ep["observations"])[:, :num_particles]
        raw = np.asarray(ep["actions"])
        a = raw if picker is None else raw.reshape(len(raw), 2, -1, 3)[:, :, picker].reshape(len(raw), 6)
        xs.append(obs[:-1])
        acts.append(a)
        nxt.append(obs[1:])
    return np.concatenate(xs), np.concatenate(acts), np.concatenate(nxt)
