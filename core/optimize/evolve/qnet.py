"""DRLOS-EMCMO's Q-network (spec §4): a small numpy MLP with dropout active at inference, trained by plain SGD.

4 inputs (the population state s1, s2, s3 and the action) -> dropout 0.2 -> 40 ReLU -> dropout 0.5 -> 40 tanh
-> 4 outputs (only the first is read). Inputs and targets are min-max scaled to [-1, 1] per feature on the
training batch (a constant feature maps to -1). No deep-learning framework: the whole network is a few arrays.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
HIDDEN, DROP_IN, DROP_HID, LR, DECAY, BATCH = 40, 0.2, 0.5, 0.01, 1e-5, 4


class Scaler:
    """Min-max scaling of each column to [-1, 1] (MATLAB's mapminmax); a constant column maps to -1."""

    def __init__(self, data: F64) -> None:
        self.lo = data.min(axis=0)
        self.span = data.max(axis=0) - self.lo

    def apply(self, data: F64) -> F64:
        safe = np.where(self.span > 0, self.span, 1.0)
        return np.where(self.span > 0, 2.0 * (data - self.lo) / safe - 1.0, -1.0)

    def invert(self, scaled: F64) -> F64:
        return (scaled + 1.0) / 2.0 * self.span + self.lo


class QNet:
    """The network, its scalers, and training; ``rng`` drives initialisation, dropout and batches."""

    def __init__(self, rng: np.random.Generator, n_in: int = 4, n_out: int = 4) -> None:
        self.rng = rng
        self.W1 = rng.normal(0.0, np.sqrt(1.0 / n_in), (n_in, HIDDEN))
        self.b1 = np.full(HIDDEN, 0.1 * np.sqrt(1.0 / HIDDEN))
        self.W2 = rng.normal(0.0, np.sqrt(1.0 / HIDDEN), (HIDDEN, HIDDEN))
        self.b2 = rng.normal(0.0, np.sqrt(1.0 / HIDDEN), HIDDEN)
        self.W3 = rng.normal(0.0, np.sqrt(1.0 / HIDDEN), (HIDDEN, n_out))
        self.b3 = rng.normal(0.0, np.sqrt(1.0 / n_out), n_out)
        self.x_scale: Scaler | None = None
        self.y_scale: Scaler | None = None
        self.steps = 0

    def _forward(self, x: F64) -> tuple[F64, tuple[F64, ...]]:
        m0 = (self.rng.random(x.shape) >= DROP_IN) / (1.0 - DROP_IN)
        x0 = x * m0
        z1 = x0 @ self.W1 + self.b1
        h1 = np.maximum(z1, 0.0)
        m1 = (self.rng.random(h1.shape) >= DROP_HID) / (1.0 - DROP_HID)
        h1d = h1 * m1
        h2 = np.tanh(h1d @ self.W2 + self.b2)
        return h2 @ self.W3 + self.b3, (x0, z1, m1, h1d, h2)

    def fit(self, X: F64, Y: F64, steps: int, refit_scaling: bool = True) -> None:
        """``steps`` SGD steps on batches of 4 rows drawn with replacement from (X, Y) (scaled)."""
        if refit_scaling or self.x_scale is None or self.y_scale is None:
            self.x_scale, self.y_scale = Scaler(X), Scaler(Y)
        Xs, Ys = self.x_scale.apply(X), self.y_scale.apply(Y)
        for _ in range(steps):
            idx = self.rng.integers(0, len(Xs), BATCH)
            out, (x0, z1, m1, h1d, h2) = self._forward(Xs[idx])
            d3 = out - Ys[idx]  # MSE gradient, summed over the batch below
            dW3, db3 = h2.T @ d3, d3.sum(axis=0)
            d2 = (d3 @ self.W3.T) * (1.0 - h2 * h2)
            dW2, db2 = h1d.T @ d2, d2.sum(axis=0)
            d1 = (d2 @ self.W2.T) * m1 * (z1 > 0)
            dW1, db1 = x0.T @ d1, d1.sum(axis=0)
            for W, dW in ((self.W1, dW1), (self.W2, dW2), (self.W3, dW3)):
                W -= LR * (dW + DECAY * W) / BATCH
            for b, db in ((self.b1, db1), (self.b2, db2), (self.b3, db3)):
                b -= LR * db / BATCH
        self.steps += steps

    def predict(self, X: F64) -> F64:
        """``(n,)`` the first output, unscaled: one stochastic pass (dropout stays on, MC-dropout style)."""
        assert self.x_scale is not None and self.y_scale is not None
        out, _ = self._forward(self.x_scale.apply(np.atleast_2d(X)))
        return self.y_scale.invert(out)[:, 0]
