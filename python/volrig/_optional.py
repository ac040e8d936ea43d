"""scipy is optional. Blender's own builds (blender.org) embed a Python with numpy but without scipy, so ``import
volrig`` and the main pipeline (load, segment, skeletonize, autorig, bind, deform and bake, the add-on's
operators) need numpy only; the few functions that need scipy import it when called, through ``scipy_module``,
which names the function in the error when scipy is missing.

Binding and skin weights are scipy.sparse CSR matrices when scipy is installed (the documented API). Without it
they are ``CSR`` below: the same arrays (``data``, ``indices``, ``indptr``, ``shape``) and the few methods volrig
itself uses (``tocsr``, ``tocsc``, row selection, ``@`` a dense array, ``toarray``); ``to_scipy`` converts.
"""
import importlib

import numpy as np

from ._volrig import VolrigError


class ScipyMissing(VolrigError, ImportError):
    """A function that needs scipy was called in a Python without scipy (a VolrigError, so the add-on reports it
    in the status bar, and an ImportError)."""


def have_scipy() -> bool:
    try:
        importlib.import_module("scipy")
    except ImportError:
        return False
    return True


def scipy_module(name: str, what: str):
    """``importlib.import_module(name)`` (e.g. "scipy.ndimage"), or a ScipyMissing naming ``what`` (the function
    or feature that needs it)."""
    try:
        return importlib.import_module(name)
    except ImportError as e:
        raise ScipyMissing(f"{what} needs scipy ({name}), which this Python does not have: install scipy into it "
                           "(Debian: apt install python3-scipy; Blender's own Python: python -m pip install scipy)"
                           ) from e


class LazyModule:
    """A scipy module imported on first use (module-level ``ndi = LazyModule("scipy.ndimage", "volrig.drawing")``):
    importing the volrig module that holds it does not need scipy; calling into it does."""

    def __init__(self, name: str, what: str):
        self._name, self._what = name, what

    def __getattr__(self, attr):
        return getattr(scipy_module(self._name, self._what), attr)


class CSR:
    """A compressed sparse matrix without scipy: row-compressed (``format == "csr"``: ``indptr`` over rows,
    ``indices`` the columns) or column-compressed (``"csc"``), as scipy.sparse lays them out."""

    def __init__(self, data, indices, indptr, shape, format: str = "csr"):
        self.data = np.asarray(data)
        self.indices = np.asarray(indices)
        self.indptr = np.asarray(indptr)
        self.shape = (int(shape[0]), int(shape[1]))
        self.format = format
        major = self.shape[0] if format == "csr" else self.shape[1]
        if len(self.indptr) != major + 1 or len(self.indices) != len(self.data) or \
                (len(self.indptr) and (self.indptr[0] != 0 or self.indptr[-1] != len(self.data))):
            raise ValueError("not a valid compressed sparse matrix")

    def __repr__(self) -> str:
        return f"<volrig CSR {self.shape} {self.format}, {self.nnz} stored {self.dtype} values (no scipy)>"

    @property
    def dtype(self):
        return self.data.dtype

    @property
    def nnz(self) -> int:
        return len(self.data)

    def _flip(self) -> "CSR":
        """The same matrix compressed the other way (entries in major order, stable: as scipy's csr_tocsc)."""
        major = self.shape[0] if self.format == "csr" else self.shape[1]
        minor = self.shape[1] if self.format == "csr" else self.shape[0]
        rows = np.repeat(np.arange(major, dtype=self.indices.dtype), np.diff(self.indptr))
        order = np.argsort(self.indices, kind="stable")
        indptr = np.zeros(minor + 1, dtype=self.indptr.dtype)
        np.cumsum(np.bincount(self.indices, minlength=minor), out=indptr[1:])
        return CSR(self.data[order], rows[order], indptr, self.shape, "csc" if self.format == "csr" else "csr")

    def tocsr(self) -> "CSR":
        return self if self.format == "csr" else self._flip()

    def tocsc(self) -> "CSR":
        return self if self.format == "csc" else self._flip()

    def copy(self) -> "CSR":
        return CSR(self.data.copy(), self.indices.copy(), self.indptr.copy(), self.shape, self.format)

    def eliminate_zeros(self) -> None:
        keep = self.data != 0
        if keep.all():
            return
        major = np.repeat(np.arange(len(self.indptr) - 1), np.diff(self.indptr))
        indptr = np.zeros(len(self.indptr), dtype=self.indptr.dtype)
        np.cumsum(np.bincount(major[keep], minlength=len(self.indptr) - 1), out=indptr[1:])
        self.data, self.indices, self.indptr = self.data[keep], self.indices[keep], indptr

    def __getitem__(self, rows) -> "CSR":
        """Rows selected by an index array or a boolean mask (in that order), as ``scipy_csr[rows]``."""
        m = self.tocsr()
        rows = np.asarray(rows)
        rows = np.flatnonzero(rows) if rows.dtype == np.bool_ else rows.astype(np.int64).reshape(-1)
        start, count = m.indptr[rows], np.diff(m.indptr)[rows]
        indptr = np.zeros(len(rows) + 1, dtype=m.indptr.dtype)
        np.cumsum(count, out=indptr[1:])
        take = np.repeat(start - indptr[:-1], count) + np.arange(indptr[-1])
        return CSR(m.data[take], m.indices[take], indptr, (len(rows), self.shape[1]))

    def __matmul__(self, other) -> np.ndarray:
        """The matrix times a dense (B,) or (B, K) array: a dense (N,) or (N, K) array."""
        m = self.tocsr()
        x = np.asarray(other)
        rows = np.repeat(np.arange(self.shape[0]), np.diff(m.indptr))
        terms = m.data.reshape((-1,) + (1,) * (x.ndim - 1)) * x[m.indices]
        out = np.zeros((self.shape[0],) + x.shape[1:], dtype=np.result_type(m.data, x))
        np.add.at(out, rows, terms)
        return out

    def toarray(self) -> np.ndarray:
        m = self.tocsr()
        out = np.zeros(self.shape, dtype=self.dtype)
        rows = np.repeat(np.arange(self.shape[0]), np.diff(m.indptr))
        np.add.at(out, (rows, m.indices), m.data)
        return out

    def to_scipy(self):
        """The scipy.sparse matrix (needs scipy)."""
        sparse = scipy_module("scipy.sparse", "CSR.to_scipy")
        cls = sparse.csr_matrix if self.format == "csr" else sparse.csc_matrix
        return cls((self.data, self.indices, self.indptr), shape=self.shape)


def csr_matrix(data, indices, indptr, shape, dtype=None):
    """``scipy.sparse.csr_matrix((data, indices, indptr), shape, dtype)`` when scipy is there, else a CSR of the
    same arrays."""
    try:
        from scipy import sparse
    except ImportError:
        return CSR(np.asarray(data, dtype=dtype), np.asarray(indices), np.asarray(indptr), shape)
    return sparse.csr_matrix((data, indices, indptr), shape=shape, dtype=dtype)


def coo_arrays(vals, rows, cols, shape):
    """(data, indices, indptr) of the CSR matrix ``scipy.sparse.csr_matrix((vals, (rows, cols)), shape)`` builds:
    entries sorted by row then column, duplicates summed (in input order), explicit zeros kept."""
    vals, rows, cols = np.asarray(vals), np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)
    order = np.lexsort((cols, rows))
    r, c, v = rows[order], cols[order], vals[order]
    first = np.ones(len(r), dtype=bool)
    first[1:] = (r[1:] != r[:-1]) | (c[1:] != c[:-1])
    starts = np.flatnonzero(first)
    data = np.add.reduceat(v, starts) if len(v) else v
    indptr = np.zeros(shape[0] + 1, dtype=np.int32)
    np.cumsum(np.bincount(r[starts], minlength=shape[0]), out=indptr[1:])
    return data, c[starts].astype(np.int32), indptr


def csr_from_coo(vals, rows, cols, shape, dtype=None):
    """``scipy.sparse.csr_matrix((vals, (rows, cols)), shape, dtype)`` when scipy is there, else the same matrix as
    a CSR."""
    try:
        from scipy import sparse
    except ImportError:
        data, indices, indptr = coo_arrays(np.asarray(vals, dtype=dtype), rows, cols, shape)
        return CSR(data, indices, indptr, shape)
    return sparse.csr_matrix((vals, (rows, cols)), shape=shape, dtype=dtype)


def matrix_quaternions(r: np.ndarray) -> np.ndarray:
    """(B, 4) unit quaternions (x, y, z, w) of (B, 3, 3) rotation matrices, without scipy: the method of
    ``scipy.spatial.transform.Rotation.from_matrix`` (Markley's: from the largest of the diagonal and the trace, so
    no cancellation), which gives the same quaternion, sign included, to rounding."""
    r = np.asarray(r, dtype=np.float64)
    diag = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    decision = np.concatenate([diag, diag.sum(axis=1, keepdims=True)], axis=1)
    choice = decision.argmax(axis=1)
    q = np.empty((len(r), 4))
    for i in range(3):
        s = np.flatnonzero(choice == i)
        j, k = (i + 1) % 3, (i + 2) % 3
        q[s, i] = 1.0 - decision[s, 3] + 2.0 * r[s, i, i]
        q[s, j] = r[s, j, i] + r[s, i, j]
        q[s, k] = r[s, k, i] + r[s, i, k]
        q[s, 3] = r[s, k, j] - r[s, j, k]
    s = np.flatnonzero(choice == 3)
    q[s, 0] = r[s, 2, 1] - r[s, 1, 2]
    q[s, 1] = r[s, 0, 2] - r[s, 2, 0]
    q[s, 2] = r[s, 1, 0] - r[s, 0, 1]
    q[s, 3] = 1.0 + decision[s, 3]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def rotation_power(R: np.ndarray) -> "callable":
    """t -> R^t for a 3x3 rotation R (same axis, t times the angle in [0, pi]), without scipy: through the
    quaternion, as ``Rotation.from_rotvec(Rotation.from_matrix(R).as_rotvec() * t).as_matrix()``, to rounding."""
    x, y, z, w = matrix_quaternions(np.asarray(R, dtype=np.float64)[None])[0]
    if w < 0:  # the rotation vector of the angle in [0, pi], as as_rotvec takes it
        x, y, z, w = -x, -y, -z, -w
    s = float(np.sqrt(x * x + y * y + z * z))
    half = float(np.arctan2(s, w))
    axis = np.array([x, y, z]) / s if s > 0 else np.zeros(3)

    def power(t: float) -> np.ndarray:
        a = half * float(t)
        qx, qy, qz = axis * np.sin(a)
        qw = np.cos(a)
        return np.array([
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])
    return power


def gaussian_filter(a: np.ndarray, sigma: float) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(a, sigma)`` for a float array without scipy, computed as scipy does it: the
    kernel exp(-x^2 / 2 sigma^2) normalised, radius int(4 sigma + 0.5), axis after axis, the borders mirrored
    ("reflect": d c b a | a b c d), sums in float64 pairing the symmetric taps, each pass stored in a's dtype."""
    radius = int(4.0 * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1)
    phi = np.exp(-0.5 / (float(sigma) * float(sigma)) * x ** 2)
    w = phi / phi.sum()
    out = np.array(a)
    for axis in range(out.ndim):
        n = out.shape[axis]
        padded = np.pad(out.astype(np.float64), [(radius, radius) if ax == axis else (0, 0)
                                                 for ax in range(out.ndim)], mode="symmetric") \
            if n >= radius else _reflect_pad(out.astype(np.float64), radius, axis)
        take = (lambda s: padded[tuple(slice(s, s + n) if ax == axis else slice(None) for ax in range(out.ndim))])
        acc = take(radius) * w[radius]
        for j in range(1, radius + 1):
            acc += (take(radius - j) + take(radius + j)) * w[radius + j]
        out = acc.astype(out.dtype)
    return out


def _reflect_pad(a: np.ndarray, radius: int, axis: int) -> np.ndarray:
    """``a`` padded by ``radius`` along ``axis`` in scipy's "reflect" mode when the axis is shorter than the radius
    (the mirror repeats: a b | b a a b | b a)."""
    n = a.shape[axis]
    idx = np.arange(-radius, n + radius)
    period = 2 * n
    m = np.mod(idx, period)
    m = np.where(m >= n, period - 1 - m, m)
    return np.take(a, m, axis=axis)
