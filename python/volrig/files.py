"""Atomic file output: write beside the target, then rename, so readers never see a partial file."""
from __future__ import annotations

import os
import stat
import tempfile
from contextlib import contextmanager


def _keep_owner(tmp: str, owner) -> None:
    """Gives ``tmp`` the replaced file's owner and group where this process may (root, or a group it is in); else
    it stays the writer's, as a new file would be (before chmod: chown clears set-id bits)."""
    if owner is None or owner == (os.geteuid(), os.getegid()):
        return
    try:
        os.chown(tmp, *owner)
    except OSError:
        try:
            os.chown(tmp, -1, owner[1])
        except OSError:
            pass


@contextmanager
def atomic_output(path: str, suffix: str = ""):
    """Yields a temporary path in the target's folder; on success it is renamed onto ``path``, on error removed.
    An existing file keeps its owner (where allowed) and permission bits; a symbolic link keeps pointing at its
    target, which is replaced.
    ``suffix`` keeps writers that insist on an ending (numpy adds ".npz", matplotlib picks the format) happy."""
    path = os.fspath(path)
    if ("\0" if isinstance(path, str) else b"\0") in path:
        from ._volrig import VolrigError
        raise VolrigError(f"{os.fsdecode(path).split(chr(0))[0]}...: a file name must not contain a NUL character")
    path = os.path.realpath(path)  # a symbolic link is written through: its target is replaced, the link stays
    folder = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp" + suffix,
                               dir=folder)
    os.close(fd)
    try:
        old = os.stat(path)  # an overwritten file keeps its owner and permission bits
        mode, owner = stat.S_IMODE(old.st_mode), (old.st_uid, old.st_gid)
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        mode, owner = 0o666 & ~umask, None  # mkstemp creates 0600; give a new file the permissions open() would
    try:
        yield tmp
        _keep_owner(tmp, owner)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
