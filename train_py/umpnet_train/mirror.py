"""Training states mirrored left-right (beyond the paper).

The benchmark camera sits in the world's plane x = 0 and scenes are placed
and turned symmetrically about it, so a state seen in a mirror is as valid
a state: a door hinged on the left becomes one hinged on the right, and a
move's outcome (its distance, its Arrow of Time) is the same for the
mirrored move. Mirroring a state means reversing its images' columns and
negating the world's x in everything that carries it: the observation's
point and normal (the runtime's own mirror, the one `--mirror-average`
uses), move directions, and per-pixel flow fields. The grasp pixel's
column is reflected. Labels are kept.

`train --mirror P`, `candidates finetune --mirror P` and `joint_net
--mirror P` show that share of each batch's states mirrored. The JointNet's
targets are per-pixel images, so unlike a move's outcome they are mirrored
too: part labels with their columns reversed (`columns`), flow and axis
fields like any field (`fields`).
"""

from __future__ import annotations

import numpy as np
import umpnet


def chosen(rng: np.random.Generator, n: int, share: float) -> np.ndarray:
    """Indices of the states of a batch of `n` to mirror. The RNG is drawn
    only for a share strictly between 0 and 1, so a run without mirroring
    (or with every state mirrored) keeps the random stream it had."""
    if share <= 0 or n == 0:
        return np.zeros(0, np.int64)
    if share >= 1:
        return np.arange(n)
    return np.flatnonzero(rng.random(n) < share)


def images(batch: np.ndarray) -> np.ndarray:
    """N x H x W x 10 observations mirrored by the runtime's rule, in the
    batch's dtype."""
    out = umpnet._umpnet.mirrored_observations(np.ascontiguousarray(batch, dtype=np.float32))
    return out.astype(batch.dtype, copy=False)


def pixels(batch: np.ndarray, width: int) -> np.ndarray:
    """(row, col) pixels of images `width` wide, with the column reflected."""
    out = batch.copy()
    out[..., 1] = width - 1 - out[..., 1]
    return out


def vectors(batch: np.ndarray) -> np.ndarray:
    """World vectors (..., 3) with x negated; NaN padding stays NaN."""
    out = batch.copy()
    out[..., 0] *= -1
    return out


def columns(batch: np.ndarray) -> np.ndarray:
    """Per-pixel labels (N x H x W x ...) with their columns reversed."""
    return np.ascontiguousarray(batch[:, :, ::-1])


def fields(batch: np.ndarray) -> np.ndarray:
    """Per-pixel world vectors (N x H x W x 3), columns reversed, x negated."""
    return vectors(columns(batch))


def states(which: np.ndarray, images_: list, pixels_: list, vectors_: list, fields_: list) -> tuple:
    """The arrays of one batch with the states at `which` mirrored, by kind:
    observations (N x H x W x 10), grasp pixels (N x 2), world vectors
    (N x ... x 3) and flow fields (N x H x W x 3). Returns four lists of
    new arrays in the same order; the inputs are not modified."""
    if not len(which):
        return images_, pixels_, vectors_, fields_
    width = images_[0].shape[2] if images_ else fields_[0].shape[2]

    def apply(parts, op):
        out = []
        for part in parts:
            part = part.copy()
            part[which] = op(part[which])
            out.append(part)
        return out

    return (
        apply(images_, images),
        apply(pixels_, lambda p: pixels(p, width)),
        apply(vectors_, vectors),
        apply(fields_, fields),
    )
