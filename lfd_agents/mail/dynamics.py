"""Learned particle dynamics for MAIL: 1D-CNN over particles + LSTM over steps.

The model maps the particle positions ``x_t`` (N, 3) and a pick-and-place action ``a_t``
to per-particle displacements ``Δx_t`` so that ``x_{t+1} = x_t + Δx_t``. Architecture (after
MAIL, thesis §5 / Table D.7, scaled to a CPU):

* per step, a 1D convolution stack over the particle index (particles in grid order, so
  neighbours in the array are neighbours on the cloth) encodes ``x_t`` into a feature vector;
* the feature and the action enter an LSTM that carries a hidden state across steps;
* a fully connected head ``Linear → LayerNorm → tanh`` outputs the (bounded) displacement
  of every particle, scaled by ``max_displacement``.

Particles are sub-sampled to ``num_points`` fixed indices (evenly spaced in the array) so the
model size does not grow with the simulator resolution; predictions for all particles are
interpolated from the nearest sub-sampled particle in the start state.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Iterable

import numpy as np
import torch
from torch import nn


@dataclass
class DynamicsConfig:
    """Sizes of :class:`ParticleDynamicsModel` (defaults fit a 2-core CPU)."""

    num_points: int = 256  #: particles kept (evenly spaced indices)
    action_dim: int = 6  #: one picker's pick xyz + place xyz (normalised)
    conv_channels: int = 32
    conv_layers: int = 4
    lstm_hidden: int = 64
    max_displacement: float = 1.0  #: metres; tanh output is scaled by this
    learning_rate: float = 1e-3
    batch_size: int = 64


class ParticleDynamicsModel(nn.Module):
    """CNN-LSTM forward model predicting per-particle displacements."""

    def __init__(self, config: DynamicsConfig):
        super().__init__()
        self.config = config
        c = config.conv_channels
        layers: list[nn.Module] = [nn.Conv1d(3, c, 3, stride=2, padding=1), nn.LeakyReLU()]
        for _ in range(config.conv_layers - 1):
            layers += [nn.Conv1d(c, c, 3, stride=2, padding=1), nn.LeakyReLU()]
        self.encoder = nn.Sequential(*layers)
        length = config.num_points
        for _ in range(config.conv_layers):
            length = (length + 1) // 2
        self.lstm = nn.LSTM(c * length + config.action_dim, config.lstm_hidden, batch_first=True)
        out = 3 * config.num_points
        self.head = nn.Sequential(nn.Linear(config.lstm_hidden, out), nn.LayerNorm(out), nn.Tanh())
        self.out_scale = nn.Parameter(torch.ones(out) * 0.1)  # learned gain after the bounded tanh

    def forward(self, points: torch.Tensor, actions: torch.Tensor,
                hidden: tuple[torch.Tensor, torch.Tensor] | None = None):
        """One or more steps.

        Args:
            points: (B, T, K, 3) particle positions at each step's start (centred inputs).
            actions: (B, T, action_dim).
        Returns:
            displacements (B, T, K, 3) and the LSTM hidden state.
        """
        b, t, k, _ = points.shape
        feat = self.encoder(points.reshape(b * t, k, 3).transpose(1, 2)).reshape(b, t, -1)
        h, hidden = self.lstm(torch.cat([feat, actions], dim=-1), hidden)
        disp = self.head(h) * self.out_scale * self.config.max_displacement
        return disp.reshape(b, t, k, 3), hidden


class LearnedDynamics:
    """Train, save, load and roll out :class:`ParticleDynamicsModel`.

    Args:
        num_particles: particles per world in the simulator (for sub-sampling indices).
        config: model sizes.
        seed: torch seed for initialisation and batching.
    """

    def __init__(self, num_particles: int, config: DynamicsConfig | None = None, seed: int = 0,
                 device: str = "cpu"):
        self.config = config or DynamicsConfig()
        self.num_particles = int(num_particles)
        k = min(self.config.num_points, self.num_particles)
        self.config.num_points = k
        self.indices = np.linspace(0, self.num_particles - 1, k).round().astype(np.int64)
        torch.manual_seed(seed)
        self.device = torch.device(device)
        self.model = ParticleDynamicsModel(self.config).to(self.device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=self.config.learning_rate)
        self.seed = seed
        self.history: list[float] = []

    # ------------------------------------------------------------------ data
    def _tensor(self, x: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(x, dtype=np.float32), device=self.device)

    def _centre(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inputs are expressed relative to the sub-sampled cloud's centroid (translation invariance)."""
        c = points.mean(axis=-2, keepdims=True)
        return points - c, c

    def fit(self, x: np.ndarray, actions: np.ndarray, x_next: np.ndarray, epochs: int = 50,
            progress: bool = False) -> list[float]:
        """Train on one-step transitions.

        Args:
            x, x_next: (M, N, 3) particle positions before and after the action.
            actions: (M, action_dim) normalised actions.
            epochs: passes over the data.
        Returns:
            mean training loss per epoch.
        """
        x, x_next = np.asarray(x)[:, self.indices], np.asarray(x_next)[:, self.indices]
        if len(x) != len(actions) or len(x) != len(x_next):
            raise ValueError(f"x, actions, x_next must have the same length, got {len(x)}, {len(actions)}, {len(x_next)}")
        xc, _ = self._centre(x)
        xt, at, dt = self._tensor(xc)[:, None], self._tensor(actions)[:, None], self._tensor(x_next - x)[:, None]
        gen = torch.Generator().manual_seed(self.seed)
        bs = self.config.batch_size
        from tqdm import trange

        losses = []
        for _ in trange(int(epochs), desc="dynamics", disable=not progress, leave=False):
            perm = torch.randperm(len(xt), generator=gen)
            total = 0.0
            for i in range(0, len(xt), bs):
                idx = perm[i:i + bs]
                pred, _ = self.model(xt[idx], at[idx])
                loss = torch.mean((pred - dt[idx]) ** 2)
                self.optimizer.zero_grad()
                loss.backward()
                self.optimizer.step()
                total += float(loss.detach()) * len(idx)
            losses.append(total / len(xt))
        self.history += losses
        return losses

    # ------------------------------------------------------------------ prediction
    @torch.no_grad()
    def rollout(self, x0: np.ndarray, action_seqs: np.ndarray) -> np.ndarray:
        """Predict sub-sampled particle positions after each action sequence.

        Args:
            x0: (N, 3) start positions (all particles).
            action_seqs: (B, H, action_dim).
        Returns:
            (B, K, 3) predicted final positions of the sub-sampled particles.
        """
        b, horizon, _ = action_seqs.shape
        pts = np.broadcast_to(np.asarray(x0)[self.indices], (b, len(self.indices), 3)).astype(np.float32)
        cur = self._tensor(pts)
        acts = self._tensor(action_seqs)
        hidden = None
        for t in range(horizon):
            c = cur.mean(dim=1, keepdim=True)
            disp, hidden = self.model((cur - c)[:, None], acts[:, t:t + 1], hidden)
            cur = cur + disp[:, 0]
        return cur.cpu().numpy()

    def predict_all(self, x0: np.ndarray, action_seq: np.ndarray) -> np.ndarray:
        """Final positions of ALL particles for one sequence (nearest sub-sampled neighbour motion)."""
        sub_final = self.rollout(x0, action_seq[None])[0]
        sub_start = np.asarray(x0)[self.indices]
        d = np.linalg.norm(np.asarray(x0)[:, None] - sub_start[None], axis=-1)
        nearest = d.argmin(axis=1)
        return np.asarray(x0) + (sub_final - sub_start)[nearest]

    # ------------------------------------------------------------------ io
    def save(self, path: str | Path) -> None:
        torch.save({"config": asdict(self.config), "num_particles": self.num_particles, "seed": self.seed,
                    "state_dict": self.model.state_dict(), "history": self.history}, str(path))

    @classmethod
    def load(cls, path: str | Path, device: str = "cpu") -> "LearnedDynamics":
        blob = torch.load(str(path), map_location=device, weights_only=False)
        obj = cls(blob["num_particles"], DynamicsConfig(**blob["config"]), seed=blob["seed"], device=device)
        obj.model.load_state_dict(blob["state_dict"])
        obj.history = list(blob["history"])
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
