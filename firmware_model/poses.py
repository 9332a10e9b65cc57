"""The one pose batch type of the fixed-point solvers: field schema, quantisation with its flags,
branch bits.

A :class:`PoseBatch` is what every fixed-point solver takes (the C solver, the scalar and
vectorised models, the soft CPU harness, the IK cores' input payload): word arrays p, a, n, o
(N, 3), the has_roll / shoulder_back / elbow_down bits and the q5 default word. Float poses become
one with :meth:`PoseBatch.quantise`, which also returns the per-row input status (the flags of
:func:`pose_words`); the IK core's payload fields are the names of :data:`FIELDS`.
"""

from __future__ import annotations

import numpy as np

from ik5r.core import status as st
from ik5r.core.fxconfig import FixedConfig, quantize
from ik5r.core.pose_fields import POSE_NAMES

#: Field names of a pose (the IK core's input payload), in the order of :meth:`PoseBatch.fields`.
FIELDS = POSE_NAMES


def pose_words(cfg: FixedConfig, p, a, n=None, o=None):
    """Poses (N, 3) floats to the solvers' input words, and the per-row input status.

    Returns (p_l, a_u, n_u, o_u, input_status): words (n_u, o_u None without n, o) and
    ``INVALID | SATURATED`` on rows with a value outside the word range (the pose cannot be given
    to the solver), ``INVALID`` on rows with a non-finite value, else 0.
    """
    values = [np.asarray(v, dtype=np.float64) for v in (p, a, n, o) if v is not None]
    fracs = [cfg.frac_length] + [cfg.frac_unit] * (len(values) - 1)
    count = len(values[0])
    finite = np.ones(count, dtype=bool)
    saturated = np.zeros(count, dtype=bool)
    words = []
    for value, frac in zip(values, fracs):
        finite &= np.isfinite(value).all(axis=1)
        word, sat = quantize(value, frac, cfg)
        saturated |= sat.any(axis=1)
        words.append(word)
    input_status = np.where(saturated, st.INVALID | st.SATURATED, np.where(finite, 0, st.INVALID))
    words += [None] * (4 - len(words))
    return (*words, input_status.astype(np.int64))


class PoseBatch:
    """Pose rows as word arrays: p, a, n, o (N, 3), roll, back, down (N,) bool, q5 (N,)."""

    def __init__(self, p, a, n, o, roll, back, down, q5):
        self.p, self.a, self.n, self.o = (np.asarray(v, dtype=np.int64).reshape(-1, 3) for v in (p, a, n, o))
        count = len(self.p)
        # Scalars are spread over the rows (copies: the C solver takes contiguous arrays).
        self.roll, self.back, self.down = (np.array(np.broadcast_to(np.asarray(v, dtype=bool), (count,)))
                                           for v in (roll, back, down))
        self.q5 = np.array(np.broadcast_to(np.asarray(q5, dtype=np.int64), (count,)))

    @classmethod
    def quantise(cls, cfg: FixedConfig, p, a, n=None, o=None, *, back=False, down=False,
                 q5=0) -> tuple["PoseBatch", np.ndarray]:
        """Float poses (cm, unit vectors; n and o both or neither) to a batch and the per-row input
        status (:func:`pose_words`). Rows without n, o carry zero words and has_roll = 0. ``q5``:
        the q5 default word(s); ``back``, ``down``: branch bits (scalars or per row)."""
        p_l, a_u, n_u, o_u, input_status = pose_words(cfg, p, a, n, o)
        has_roll = n_u is not None
        zeros = np.zeros_like(p_l)
        batch = cls(p_l, a_u, n_u if has_roll else zeros, o_u if has_roll else zeros, has_roll,
                    back, down, q5)
        return batch, input_status

    @property
    def branch(self) -> np.ndarray:
        """Branch index of each row: 2 * shoulder_back + elbow_down (``reference.branch_bits``)."""
        return 2 * self.back.astype(np.int64) + self.down

    def with_branch(self, branch) -> "PoseBatch":
        """The same poses solved on ``branch`` (index or per-row indices)."""
        branch = np.asarray(branch)
        return PoseBatch(self.p, self.a, self.n, self.o, self.roll, (branch & 2) != 0, (branch & 1) != 0,
                         self.q5)

    def __len__(self):
        return len(self.p)

    def args(self):
        """The arguments of every ``solve_batch``: p, a, n, o, roll, back, down, q5."""
        return self.p, self.a, self.n, self.o, self.roll, self.back, self.down, self.q5

    def solve(self, solve_batch):
        """(q words (N, 5), status (N,)) of a fixed-point solver's ``solve_batch``."""
        return solve_batch(*self.args())

    def __getitem__(self, index):
        return PoseBatch(*(v[index] for v in self.args()))

    def fields(self) -> dict[str, np.ndarray]:
        """int64 columns by :data:`FIELDS` name."""
        cols = [*self.p.T, *self.a.T, *self.n.T, *self.o.T, self.roll, self.back, self.down, self.q5]
        return {name: np.asarray(col, dtype=np.int64) for name, col in zip(FIELDS, cols)}

    @classmethod
    def from_fields(cls, f: dict[str, np.ndarray]) -> "PoseBatch":
        def vec(name):
            return np.stack([f[name + axis] for axis in "xyz"], axis=1)
        return cls(vec("p"), vec("a"), vec("n"), vec("o"), np.asarray(f["has_roll"]) != 0,
                   np.asarray(f["shoulder_back"]) != 0, np.asarray(f["elbow_down"]) != 0, f["q5_default"])

    def driver_lines(self):
        cols = np.column_stack([self.p, self.a, self.n, self.o, self.roll, self.back, self.down, self.q5])
        return ["S " + " ".join(map(str, row)) for row in cols.tolist()]


def concat(*batches: PoseBatch) -> PoseBatch:
    return PoseBatch(*(np.concatenate(cols) for cols in zip(*(b.args() for b in batches))))


def every_branch(p, a, n, o, q5) -> PoseBatch:
    """Each pose with the 4 branches, with and without n/o: 8 rows per pose."""
    count = len(p)
    rep = lambda v: np.repeat(np.asarray(v), 8, axis=0)  # noqa: E731
    variant = np.tile(np.arange(8), count)
    return PoseBatch(rep(p), rep(a), rep(n), rep(o), (variant & 4) != 0, (variant & 2) != 0,
                     (variant & 1) != 0, rep(q5))
