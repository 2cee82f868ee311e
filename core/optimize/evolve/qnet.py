"""DRLOS-EMCMO's Q-network (spec §4): a small numpy MLP with dropout active at inference, trained by plain SGD.

4 inputs (the population state s1, s2, s3 and the action) -> dropout 0.2 -> 40 ReLU -> dropout 0.5 -> 40 tanh
-> 4 outputs (only the first is read). Inputs and targets are min-max scaled to [-1, 1] per feature on the
training batch (a constant feature maps to -1). No deep-learning framework: the whole network is a few arrays,
and its passes and SGD steps are compiled (the first training's 80 000 steps of 4 rows took 3.5 s as numpy
calls, most of a DRLOS-EMCMO run).
"""

from __future__ import annotations

import numba
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

    def params(self) -> tuple[F64, F64, F64, F64, F64, F64]:
        """W1, b1, W2, b2, W3, b3 (updated in place by :meth:`fit`)."""
        return self.W1, self.b1, self.W2, self.b2, self.W3, self.b3

    def fit(self, X: F64, Y: F64, steps: int, refit_scaling: bool = True) -> None:
        """``steps`` SGD steps on batches of 4 rows drawn with replacement from (X, Y) (scaled)."""
        if refit_scaling or self.x_scale is None or self.y_scale is None:
            self.x_scale, self.y_scale = Scaler(X), Scaler(Y)
        Xs = np.ascontiguousarray(self.x_scale.apply(X), dtype=np.float64)
        Ys = np.ascontiguousarray(self.y_scale.apply(Y), dtype=np.float64)
        _sgd(self.rng, Xs, Ys, *self.params(), int(steps))
        self.steps += steps

    def forward(self, x: F64) -> tuple[F64, ...]:
        """One pass of the scaled ``(b, 4)`` rows with dropout: x0, z1, m1, h1d, h2 and the ``(b, 4)`` outputs
        (see :func:`_layers`)."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        b, H = len(x), self.W2.shape[0]
        bufs = (np.empty(x.shape), np.empty((b, H)), np.empty((b, H)), np.empty((b, H)), np.empty((b, H)),
                np.empty((b, self.W3.shape[1])))
        _layers(self.rng, x, *self.params(), *bufs)
        return bufs

    def predict(self, X: F64) -> F64:
        """``(n,)`` the first output, unscaled: one stochastic pass (dropout stays on, MC-dropout style)."""
        assert self.x_scale is not None and self.y_scale is not None
        out = self.forward(self.x_scale.apply(np.atleast_2d(X)))[-1]
        return self.y_scale.invert(out)[:, 0]


@numba.njit(cache=True)
def _layers(rng: np.random.Generator, x: F64, W1: F64, b1: F64, W2: F64, b2: F64, W3: F64, b3: F64, x0: F64,
            z1: F64, m1: F64, h1d: F64, h2: F64, out: F64) -> None:  # pragma: no cover - compiled
    # One pass of the rows of x with dropout, into the buffers: x0 the kept inputs (scaled by 1 / keep rate), z1
    # the first layer before its ReLU, m1 its dropout mask, h1d its output, h2 the second layer's, out the
    # network's. The masks are drawn as numpy would draw two arrays: the inputs' first, each row by row.
    b, n_in = x.shape
    H, n_out = W2.shape[0], W3.shape[1]
    for r in range(b):
        for k in range(n_in):
            x0[r, k] = x[r, k] * ((rng.random() >= DROP_IN) / (1.0 - DROP_IN))
    for r in range(b):
        for h in range(H):
            m1[r, h] = (rng.random() >= DROP_HID) / (1.0 - DROP_HID)
    for r in range(b):
        z1[r] = 0.0
        for k in range(n_in):
            a = x0[r, k]
            for h in range(H):
                z1[r, h] += a * W1[k, h]
        h2[r] = 0.0
        for k in range(H):
            z1[r, k] += b1[k]
            h1d[r, k] = max(z1[r, k], 0.0) * m1[r, k]
            a = h1d[r, k]
            if a == 0.0:  # off or dropped (three in four): adds nothing
                continue
            for h in range(H):
                h2[r, h] += a * W2[k, h]
        out[r] = 0.0
        for k in range(H):
            h2[r, k] = np.tanh(h2[r, k] + b2[k])
            a = h2[r, k]
            for o in range(n_out):
                out[r, o] += a * W3[k, o]
        for o in range(n_out):
            out[r, o] += b3[o]


@numba.njit(cache=True)
def _sgd(rng: np.random.Generator, Xs: F64, Ys: F64, W1: F64, b1: F64, W2: F64, b2: F64, W3: F64, b3: F64,
         steps: int) -> None:  # pragma: no cover - compiled
    # ``steps`` SGD steps on the squared error of BATCH rows drawn with replacement (each step: the rows, then
    # the pass's masks), with weight decay on the weights; the parameters are updated in place.
    n_in, H, n_out = W1.shape[0], W2.shape[0], W3.shape[1]
    x0, z1, m1, h1d = np.empty((BATCH, n_in)), np.empty((BATCH, H)), np.empty((BATCH, H)), np.empty((BATCH, H))
    h2, out = np.empty((BATCH, H)), np.empty((BATCH, n_out))
    d1, d2, d3 = np.empty((BATCH, H)), np.empty((BATCH, H)), np.empty((BATCH, n_out))
    dW1, dW2, dW3 = np.empty_like(W1), np.empty_like(W2), np.empty_like(W3)
    for _ in range(steps):
        idx = rng.integers(0, len(Xs), BATCH)
        _layers(rng, Xs[idx], W1, b1, W2, b2, W3, b3, x0, z1, m1, h1d, h2, out)
        dW1[:], dW2[:], dW3[:] = 0.0, 0.0, 0.0
        for r in range(BATCH):
            for o in range(n_out):
                d3[r, o] = out[r, o] - Ys[idx[r], o]  # the squared error's gradient (halved)
            for k in range(H):
                a, s = h2[r, k], 0.0
                for o in range(n_out):
                    dW3[k, o] += a * d3[r, o]
                    s += d3[r, o] * W3[k, o]
                d2[r, k] = s * (1.0 - a * a)
            for k in range(H):  # a unit that is off or dropped passes no gradient: skipped
                a, s = h1d[r, k], 0.0
                if a != 0.0:
                    for h in range(H):
                        dW2[k, h] += a * d2[r, h]
                if m1[r, k] != 0.0 and z1[r, k] > 0:
                    for h in range(H):
                        s += d2[r, h] * W2[k, h]
                d1[r, k] = s * m1[r, k] * (z1[r, k] > 0)
            for k in range(n_in):
                a = x0[r, k]
                for h in range(H):
                    dW1[k, h] += a * d1[r, h]
        _descend(W1, b1, dW1, d1)
        _descend(W2, b2, dW2, d2)
        _descend(W3, b3, dW3, d3)


@numba.njit(cache=True)
def _descend(W: F64, b: F64, dW: F64, d: F64) -> None:  # pragma: no cover - compiled
    # One step on a layer: the weights by their gradient plus decay, the biases by the batch's summed deltas.
    for k in range(W.shape[0]):
        for h in range(W.shape[1]):
            W[k, h] -= LR * (dW[k, h] + DECAY * W[k, h]) / BATCH
    for h in range(len(b)):
        s = 0.0
        for r in range(d.shape[0]):
            s += d[r, h]
        b[h] -= LR * s / BATCH
