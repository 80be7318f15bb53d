"""The output writer: every output of a command appears complete, or nothing changes.

A command opens one :class:`Outputs` before its work, asks it for a staging path
per output and writes there; leaving the ``with`` block without an exception
commits every output, any exception aborts them all::

    with Outputs() as outs:
        out = outs.directory(args.out, option="--out")   # checked now, before the work
        js = outs.file(args.json, option="--json") if args.json else None
        ... write out / "model.bin", js ...             # staging paths beside the targets

* A directory output is built in a temporary folder beside OUT and swapped in with
  one rename (``renameat2(RENAME_EXCHANGE)`` when OUT exists; entries of the old OUT
  that the command does not write are carried over as hard links first), so the
  old result stays intact until the swap and is removed after it. When OUT is the
  working directory (or holds it) the command's entries are swapped into it one by
  one instead, each by one rename, with rollback: renaming the working directory
  away would leave the shell in a deleted folder.
* A file output is a temporary file beside it, renamed over it; a file output inside
  an output folder of the same command is written into that folder's staging and
  lands with the folder.
* Several outputs commit in order; if a later one fails the earlier ones are
  swapped back. On any failure the staging files go, and so does every folder
  this writer created: no empty output folder is left behind.
* Problems with an output path (it is a file where a folder is expected or the
  reverse, lies under a file, is not writable, the disk is full) are
  AbbeInputErrors naming the path and the option, raised before the work where
  they can be seen then.
"""

from __future__ import annotations

import ctypes
import errno
import os
import secrets
import shutil
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from abbe.errors import AbbeInputError

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
                 errno.EIO, errno.ENAMETOOLONG, errno.ENOTDIR, errno.EISDIR, errno.EEXIST}


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2); False if the system cannot."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    e = ctypes.get_errno()
    if e in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
        return False
    raise OSError(e, os.strerror(e), str(b))


def _sibling(path: Path, tag: str) -> Path:
    """An unused name beside ``path`` (hidden, tagged, unique to this process)."""
    return path.parent / f".{path.name}.abbe-{tag}-{os.getpid()}-{secrets.token_hex(4)}"


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def _link_tree(src: Path, dst: Path) -> None:
    """Recreate ``src`` at ``dst`` with hard links to its files (copies where linking fails)."""
    st = os.lstat(src)
    if stat.S_ISLNK(st.st_mode):
        os.symlink(os.readlink(src), dst)
    elif stat.S_ISDIR(st.st_mode):
        os.mkdir(dst)
        for e in os.scandir(src):
            _link_tree(Path(e.path), dst / e.name)
        os.chmod(dst, stat.S_IMODE(st.st_mode))
    elif stat.S_ISREG(st.st_mode):
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)
    # sockets, FIFOs, devices inside an output folder are not carried over


def _inside(path: Path, root: Path) -> bool:
    try:
        path.relative_to(root)
        return True
    except ValueError:
        return False


@dataclass
class _Target:
    kind: str  # "dir", "file" or "nested" (a file inside a "dir" target's staging)
    final: Path
    option: str
    staging: Path
    existed: bool = False
    per_entry: bool = False
    backup: Path | None = None
    done: list[tuple[str, Path, Path]] = field(default_factory=list)  # (how, a, b) to undo


class Outputs:
    """The outputs of one command, committed together (module docstring)."""

    def __init__(self) -> None:
        self._targets: list[_Target] = []
        self._created: list[Path] = []  # folders this writer made, parents first
        self._closed = False

    # ------------------------------------------------------------------ preparing
    def _err(self, path: Path, option: str, msg: str) -> AbbeInputError:
        return AbbeInputError(msg, file=str(path), field=option)

    def _parent(self, path: Path, option: str, create: bool = True) -> Path:
        """Make (and remember) the missing parents of ``path``; check it can be written."""
        if "\0" in str(path):
            raise self._err(Path(str(path).replace("\0", "\\0")), option,
                            "the path contains a NUL byte")
        parent = path.parent
        missing: list[Path] = []
        p = parent
        while not p.exists() and not p.is_symlink():
            missing.append(p)
            if p.parent == p:
                break
            p = p.parent
        if p.is_symlink() and not p.exists():
            raise self._err(path, option, f"{p} is a dangling symbolic link")
        if not p.is_dir():
            raise self._err(path, option, f"cannot write here: {p} is a file, not a folder")
        if not os.access(p, os.W_OK | os.X_OK):
            raise self._err(path, option, f"cannot write here: permission denied in {p}")
        for q in reversed(missing if create else []):
            try:
                os.mkdir(q)
            except FileExistsError:
                continue
            except OSError as exc:
                raise self._err(path, option, f"cannot create {q}: {exc.strerror}") from None
            self._created.append(q)
        return parent

    def _writable_folder(self, final: Path, option: str) -> None:
        """An existing output folder the user made read-only is theirs to protect:
        refuse it before the work (the new folder would carry its mode too)."""
        if final.is_dir() and not os.access(final, os.W_OK | os.X_OK):
            raise self._err(final, option, "the output folder is read-only (permission denied); "
                                           "make it writable or choose another folder")

    @staticmethod
    def _resolve(path: str | Path) -> Path:
        p = Path(os.path.abspath(os.fspath(path)))
        try:
            if p.is_symlink() and p.exists():
                p = Path(os.path.realpath(p))  # write through the user's link, keep it
            p.exists()
        except OSError as exc:   # a folder on the way that we may not enter
            raise AbbeInputError(f"cannot use this path: {exc.strerror}", file=str(p)) from None
        return p

    def check_directory(self, path: str | Path, *, option: str = "--out") -> None:
        """Check now that ``path`` can become an output folder (creates nothing)."""
        final = self._resolve(path)
        if final.exists() and not final.is_dir():
            raise self._err(final, option, "exists and is not a folder")
        self._writable_folder(final, option)
        self._parent(final, option, create=False)

    def check_file(self, path: str | Path, *, option: str) -> None:
        """Check now that ``path`` can become an output file (creates nothing)."""
        final = self._resolve(path)
        if final.is_dir():
            raise self._err(final, option, "is a folder, expected a file name")
        if final.exists() and not final.is_file():
            raise self._err(final, option, "exists and is not a regular file")
        self._parent(final, option, create=False)

    def directory(self, path: str | Path, *, option: str = "--out") -> Path:
        """A staging folder for the output folder ``path``; checked now."""
        final = self._resolve(path)
        if final.exists() and not final.is_dir():
            raise self._err(final, option, "exists and is not a folder")
        self._writable_folder(final, option)
        parent = self._parent(final, option)
        try:
            staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.abbe-tmp-", dir=parent))
        except OSError as exc:
            raise self._err(final, option, f"cannot write here: {exc.strerror}") from None
        mode = 0o777 & ~_umask()
        if final.is_dir():
            mode = stat.S_IMODE(os.stat(final).st_mode)
        os.chmod(staging, mode)
        cwd = Path(os.getcwd())
        t = _Target("dir", final, option, staging, existed=final.is_dir(),
                    per_entry=final.is_dir() and _inside(cwd, final))
        self._targets.append(t)
        return staging

    def file(self, path: str | Path, *, option: str) -> Path:
        """A staging file for the output file ``path``; checked now. A file inside an
        output folder asked for before (``--json OUT/summary.json`` beside ``-o OUT``)
        is staged inside that folder's staging and lands with it."""
        final = self._resolve(path)
        if final.is_dir():
            raise self._err(final, option, "is a folder, expected a file name")
        if final.exists() and not final.is_file():
            raise self._err(final, option, "exists and is not a regular file")
        for d in self._targets:
            if d.final == final:
                raise self._err(final, option, f"is also the path of {d.option}")
            if d.kind == "dir" and _inside(final, d.final):
                return self._nested_file(final, option, d)
        parent = self._parent(final, option)
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.abbe-tmp-", dir=parent)
        except OSError as exc:
            raise self._err(final, option, f"cannot write here: {exc.strerror}") from None
        os.close(fd)
        os.chmod(tmp, 0o666 & ~_umask())
        t = _Target("file", final, option, Path(tmp), existed=final.exists())
        self._targets.append(t)
        return Path(tmp)

    def _nested_file(self, final: Path, option: str, d: _Target) -> Path:
        """Stage ``final`` at its place inside the staging of the output folder ``d``."""
        staged = d.staging / final.relative_to(d.final)
        if os.path.lexists(staged):
            raise self._err(final, option, f"is already a file of {d.option}")
        try:
            staged.parent.mkdir(parents=True, exist_ok=True)
            staged.touch(mode=0o666 & ~_umask())
        except OSError as exc:
            raise self._err(final, option, f"cannot write here: {exc.strerror}") from None
        self._targets.append(_Target("nested", final, option, staged, existed=final.exists()))
        return staged

    def staging_of(self, path: str | Path) -> Path:
        """The staging path already given for the output ``path``."""
        final = self._resolve(path)
        for t in self._targets:
            if t.final == final:
                return t.staging
        raise KeyError(str(path))

    # ------------------------------------------------------------------ committing
    def _commit_one(self, t: _Target) -> None:
        if t.kind == "nested":  # inside a staged folder: lands with it
            return
        if t.kind == "file":
            if t.existed:
                t.backup = _sibling(t.final, "old")
                os.link(t.final, t.backup)
            os.replace(t.staging, t.final)
            t.done.append(("replace", t.staging, t.final))
            return
        if not t.existed:
            if t.final.exists():
                raise self._err(t.final, t.option, "appeared while the command ran")
            os.rename(t.staging, t.final)
            t.done.append(("rename", t.staging, t.final))
            return
        if t.per_entry:
            for e in sorted(os.listdir(t.staging)):
                src, dst = t.staging / e, t.final / e
                if os.path.lexists(dst):
                    if not _exchange(src, dst):
                        raise OSError(errno.ENOTSUP, "cannot swap entries atomically here", str(dst))
                    t.done.append(("exchange", src, dst))
                else:
                    os.rename(src, dst)
                    t.done.append(("rename", src, dst))
            return
        new = {e for e in os.listdir(t.staging)}
        for e in os.listdir(t.final):
            if e not in new:
                _link_tree(t.final / e, t.staging / e)
        if _exchange(t.staging, t.final):
            t.done.append(("exchange", t.staging, t.final))
            return
        old = _sibling(t.final, "old")
        os.rename(t.final, old)
        try:
            os.rename(t.staging, t.final)
        except OSError:
            os.rename(old, t.final)
            raise
        t.backup = old
        t.done.append(("moved", old, t.final))

    def _undo(self, t: _Target) -> None:
        for how, a, b in reversed(t.done):
            try:
                if how == "exchange":
                    _exchange(a, b)
                elif how == "rename":
                    os.rename(b, a)
                elif how == "replace" and t.backup is not None:
                    os.replace(t.backup, b)
                    t.backup = None
                elif how == "replace":
                    os.unlink(b)
                elif how == "moved":
                    os.rename(b, t.staging)
                    os.rename(a, b)
                    t.backup = None
            except OSError:
                pass
        t.done.clear()

    def commit(self) -> None:
        """Swap every staged output into place (all or none)."""
        if self._closed:
            return
        done: list[_Target] = []
        try:
            for t in self._targets:
                self._commit_one(t)
                done.append(t)
        except BaseException as exc:
            # any failure (a write error, an output that appeared meanwhile, a signal):
            # the committed outputs go back, the staging goes
            for t in [*done, *(t for t in self._targets if t.done and t not in done)][::-1]:
                self._undo(t)
            self.abort()
            if isinstance(exc, OSError) and not isinstance(exc, AbbeInputError):
                raise AbbeInputError(f"cannot write: {exc.strerror or exc}",
                                     file=str(exc.filename or self._targets[0].final),
                                     field=self._targets[0].option if self._targets else None
                                     ) from None
            raise
        self._closed = True
        for t in self._targets:  # the old results, now out of the way
            leftover = t.staging if (t.kind == "dir" and t.existed) else None
            for p in (leftover, t.backup):
                if p is not None and os.path.lexists(p):
                    if p.is_dir() and not p.is_symlink():
                        shutil.rmtree(p, ignore_errors=True)
                    else:
                        p.unlink(missing_ok=True)

    def abort(self) -> None:
        """Remove every staging path and every folder this writer created."""
        if self._closed:
            return
        self._closed = True
        for t in self._targets:
            if os.path.lexists(t.staging):
                if t.staging.is_dir() and not t.staging.is_symlink():
                    shutil.rmtree(t.staging, ignore_errors=True)
                else:
                    t.staging.unlink(missing_ok=True)
            if t.backup is not None and os.path.lexists(t.backup):
                t.backup.unlink(missing_ok=True) if not t.backup.is_dir() else None
        for q in reversed(self._created):
            try:
                os.rmdir(q)
            except OSError:
                pass

    def __enter__(self) -> "Outputs":
        return self

    def __exit__(self, et: Any, ev: Any, tb: Any) -> bool:
        if et is None:
            self.commit()
            return False
        self.abort()
        if isinstance(ev, OSError) and not isinstance(ev, AbbeInputError) and \
                ev.errno in _WRITE_ERRNOS and any(
                    ev.filename and _inside(Path(os.path.abspath(ev.filename)), t.staging.parent)
                    for t in self._targets):
            t0 = self._targets[0]
            raise AbbeInputError(f"cannot write: {ev.strerror}", file=str(t0.final),
                                 field=t0.option) from None
        return False


def atomic_write_many(files: dict[Path, bytes], option: str = "--out") -> None:
    """Write several files, all or none (one :class:`Outputs`)."""
    with Outputs() as outs:
        for path, content in files.items():
            outs.file(path, option=option).write_bytes(content)


def atomic_write(path: Path, content: bytes, option: str = "--out") -> None:
    """Write ``content`` to ``path`` atomically (a temporary file beside it, renamed)."""
    atomic_write_many({Path(path): content}, option=option)
