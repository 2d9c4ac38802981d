"""FIFO replay buffers (the paper: 6400 samples) with balanced sampling.

Images are stored as float16 to halve memory; each direction sample points
to its sequence's reference image, which lives in a ring of its own that
turns over more slowly than the samples that use it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


class Ring:
    def __init__(self, capacity: int):
        self.capacity, self.size, self.next = capacity, 0, 0
        self.generation = np.full(capacity, -1, dtype=np.int64)
        self.count = 0

    def slot(self) -> tuple[int, int]:
        i = self.next
        self.generation[i] = self.count
        self.count += 1
        self.next = (self.next + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        return i, int(self.generation[i])


_RINGS = ("refs", "pos", "dir")


class Replay:
    """With `fields`, each position and direction sample also keeps its image's
    articulation flow (H x W x 3, the simulator's dense label; `aux_fields`)."""

    def __init__(self, capacity: int, shape: tuple[int, int, int], fields: bool = False):
        h, w, c = shape
        self.refs = Ring(capacity)
        self.ref_images = np.zeros((capacity, h, w, c), np.float16)
        # Positions: the image the pixel was chosen on, the pixel, success.
        self.pos = Ring(capacity)
        self.pos_images = np.zeros((capacity, h, w, c), np.float16)
        self.pos_pixels = np.zeros((capacity, 2), np.int64)
        self.pos_labels = np.zeros(capacity, np.int64)
        # Directions: image before the action, gripper pixel, direction, labels, reference slot.
        self.dir = Ring(capacity)
        self.dir_images = np.zeros((capacity, h, w, c), np.float16)
        self.dir_pixels = np.zeros((capacity, 2), np.int64)
        self.dir_vectors = np.zeros((capacity, 3), np.float32)
        self.dir_dist = np.zeros(capacity, np.float32)
        self.dir_aot = np.zeros(capacity, np.int64)
        self.dir_ref = np.zeros(capacity, np.int64)
        self.dir_ref_gen = np.zeros(capacity, np.int64)
        self.pos_flow = np.zeros((capacity, h, w, 3), np.float16) if fields else None
        self.dir_flow = np.zeros((capacity, h, w, 3), np.float16) if fields else None

    def add_reference(self, image) -> tuple[int, int]:
        i, g = self.refs.slot()
        self.ref_images[i] = image
        return i, g

    def add_position(self, image, pixel, label: int, flow=None):
        i, _ = self.pos.slot()
        self.pos_images[i], self.pos_pixels[i], self.pos_labels[i] = image, pixel, label
        if self.pos_flow is not None:
            self.pos_flow[i] = 0.0 if flow is None else flow

    def add_direction(self, image, pixel, direction, r_dist: float, aot: int, ref: tuple[int, int], flow=None):
        i, _ = self.dir.slot()
        if self.dir_flow is not None:
            self.dir_flow[i] = 0.0 if flow is None else flow
        self.dir_images[i], self.dir_pixels[i], self.dir_vectors[i] = image, pixel, direction
        self.dir_dist[i], self.dir_aot[i] = r_dist, aot
        self.dir_ref[i], self.dir_ref_gen[i] = ref

    def sample_positions(self, rng: np.random.Generator, batch: int, flows: bool = False):
        """Balanced 1:1 successful/unsuccessful positions (as far as the buffer
        allows); with `flows`, their images' flow fields last."""
        n = self.pos.size
        labels = self.pos_labels[:n]
        idx = _balanced(rng, [np.flatnonzero(labels == k) for k in (1, 0)], batch)
        out = (self.pos_images[idx], self.pos_pixels[idx], self.pos_labels[idx])
        return (*out, self.pos_flow[idx]) if flows else out

    def sample_directions(self, rng: np.random.Generator, batch: int, groups: str = "aot", flows: bool = False):
        """Balanced over `groups`: "aot" 1:1:1 over AoT classes, "binary" 1:1
        moved / not moved, "moved" only samples that moved the object; skips
        samples whose reference was overwritten. With `flows`, the images' flow
        fields last."""
        n = self.dir.size
        alive = self.refs.generation[self.dir_ref[:n]] == self.dir_ref_gen[:n]
        aot = self.dir_aot[:n]
        if groups == "binary":
            pools = [np.flatnonzero(alive & (aot == 0)), np.flatnonzero(alive & (aot != 0))]
        elif groups == "moved":
            pools = [np.flatnonzero(alive & (aot != 0))]
        elif groups == "aot":
            pools = [np.flatnonzero(alive & (aot == k)) for k in (-1, 0, 1)]
        else:
            raise ValueError(f"groups is {groups!r}, expected aot, binary or moved")
        idx = _balanced(rng, pools, batch)
        out = (
            self.dir_images[idx],
            self.ref_images[self.dir_ref[idx]],
            self.dir_pixels[idx],
            self.dir_vectors[idx],
            self.dir_dist[idx],
            self.dir_aot[idx],
        )
        return (*out, self.dir_flow[idx]) if flows else out

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: v for k, v in vars(self).items() if isinstance(v, np.ndarray)}

    def save(self, path, epoch: int) -> None:
        """Writes the whole buffer (samples and ring positions) so that a resumed
        run continues on the same data; written beside and renamed, so an
        interrupted save never replaces a good file with a broken one."""
        path = Path(path)
        state = dict(self.arrays(), epoch=np.array(epoch))
        for name in _RINGS:
            ring = getattr(self, name)
            state[f"{name}.generation"] = ring.generation
            state[f"{name}.counters"] = np.array([ring.size, ring.next, ring.count], np.int64)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, **state)
        tmp.replace(path)

    def load(self, path) -> int:
        """Restores a buffer written by `save`; shapes must match this one's.
        Returns the epoch it was saved at."""
        with np.load(path) as data:
            for name, arr in self.arrays().items():
                if name not in data or data[name].shape != arr.shape:
                    found = data[name].shape if name in data else "nothing"
                    raise ValueError(f"{path}: `{name}` has shape {found}, expected {arr.shape}")
                arr[...] = data[name]
            for name in _RINGS:
                ring = getattr(self, name)
                ring.generation[...] = data[f"{name}.generation"]
                ring.size, ring.next, ring.count = (int(x) for x in data[f"{name}.counters"])
            return int(data["epoch"])

    def __len__(self) -> int:
        return self.dir.size


def _balanced(rng: np.random.Generator, groups: list[np.ndarray], batch: int) -> np.ndarray:
    groups = [g for g in groups if len(g)]
    if not groups:
        return np.zeros(0, np.int64)
    per = [batch // len(groups) + (1 if k < batch % len(groups) else 0) for k in range(len(groups))]
    return np.concatenate([rng.choice(g, size=m, replace=len(g) < m) for g, m in zip(groups, per, strict=True)])


class DenseReplay:
    """States with K simulated directions each (dense labels): the image is kept
    once per state, and a batch trains the decoder on all K directions of its
    states in one encoder pass. References live in the main buffer's ring."""

    def __init__(self, capacity: int, shape: tuple[int, int, int], k: int):
        self.ring = Ring(capacity)
        self.images = np.zeros((capacity, *shape), np.float16)
        self.pixels = np.zeros((capacity, 2), np.int64)
        self.vectors = np.zeros((capacity, k, 3), np.float32)
        self.dist = np.zeros((capacity, k), np.float32)
        self.aot = np.zeros((capacity, k), np.int64)
        self.ref = np.zeros(capacity, np.int64)
        self.ref_gen = np.zeros(capacity, np.int64)

    def add(self, image, pixel, directions, r_dist, aot, ref: tuple[int, int]):
        i, _ = self.ring.slot()
        self.images[i], self.pixels[i], self.vectors[i] = image, pixel, directions
        self.dist[i], self.aot[i] = r_dist, aot
        self.ref[i], self.ref_gen[i] = ref

    def sample(self, rng: np.random.Generator, states: int, refs: Ring, ref_images: np.ndarray):
        """Uniform over states whose reference is still in `refs`."""
        n = self.ring.size
        alive = np.flatnonzero(refs.generation[self.ref[:n]] == self.ref_gen[:n])
        if not len(alive):
            return None
        idx = rng.choice(alive, size=min(states, len(alive)), replace=False)
        return (
            self.images[idx],
            ref_images[self.ref[idx]],
            self.pixels[idx],
            self.vectors[idx],
            self.dist[idx],
            self.aot[idx],
        )

    def __len__(self) -> int:
        return self.ring.size
