"""Writing results: output paths probed before any work, atomic writes, JSON-ready data.

Every command that writes checks its output paths first (`check_output_path`, `check_output_dir`), so
an unwritable path stops in one line before a long computation; results are written to a temporary
file of an unpredictable name and renamed (`write_text_atomic`), so a crash never leaves half a
file and a symlink planted beside the output is never followed; '-' is stdout; a device node, FIFO
or /dev/stdout is written through, never replaced by a regular file.
"""

from __future__ import annotations

import errno
import os
import stat
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from qmt_drake.errors import QmtInputError


def _probe_folder(folder: Path, what: str) -> None:
    """Create `folder` if missing and write + remove a scratch file in it; one line if that fails."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise QmtInputError(f"{what}: {folder} is a file, not a folder; choose another path") from None
    except OSError as exc:
        raise QmtInputError(f"{what}: cannot create folder {folder} ({exc.strerror}); choose another "
                            "path") from None
    if not folder.is_dir():
        raise QmtInputError(f"{what}: {folder} is not a folder; choose another path")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".qmt-drake-probe-"):
            pass
    except OSError as exc:
        raise QmtInputError(f"{what}: folder {folder} is not writable ({exc.strerror}); choose another "
                            "path") from None


# Flags whose output makes no sense on stdout ('-'): an HTML replay, a figure, a checkpoint, a
# folder. A user who wants one piped gives /dev/stdout, which is written through (write_text_atomic).
NOT_STDOUT_FLAGS = ("--record", "--recording", "--execute", "--checkpoint", "--out", "--success-out")


def is_stdout(path) -> bool:
    """True when `path` is '-', the conventional name of standard output."""
    return path is not None and str(path) == "-"


def check_one_stdout(outputs: dict) -> None:
    """At most one of {flag: path} may be '-' (two results interleaved on stdout are unreadable)."""
    dash = [flag for flag, path in outputs.items() if is_stdout(path)]
    if len(dash) > 1:
        raise QmtInputError(f"{' and '.join(dash)} all write to stdout ('-'); give all but one of them a file name")


def check_output_path(path: str | Path | None, flag: str) -> None:
    """Before any long computation: `path` (a file to be written; '-' is stdout) must not be a
    directory, and its folder must exist or be creatable (it is created) and be writable (a
    scratch file is written and removed). A device node, FIFO or symlink is accepted (it is written
    through, never replaced, see write_text_atomic). One-line QmtInputError naming the flag."""
    if path is None:
        return
    if is_stdout(path):
        if flag in NOT_STDOUT_FLAGS:
            raise QmtInputError(f"{flag} -: this output is not written to stdout; give a file name (or "
                                "/dev/stdout to pipe it)")
        return
    if str(path) == "":
        raise QmtInputError(f"{flag}: empty path; give a file name")
    p = Path(path)
    kind = _classify(p, flag)
    if kind == "through":
        return
    if p.exists() and not os.access(p, os.W_OK):
        raise QmtInputError(f"{flag} {p} exists and is not writable; choose another path")
    _probe_folder(kind.parent if str(kind.parent) else Path("."), f"{flag} {p}")


def check_output_dir(path: str | Path, flag: str) -> None:
    """Like check_output_path for a folder results are written into (created if missing)."""
    if str(path) == "":
        raise QmtInputError(f"{flag}: empty path; give a folder")
    if is_stdout(path):
        raise QmtInputError(f"{flag} -: results go into a folder, not stdout; give a folder name")
    _probe_folder(Path(path), f"{flag} {path}")


def _own_fd(p: Path) -> int | None:
    """The descriptor N when the chain of symlinks from `p` reaches /proc/self/fd/N (/dev/stdout,
    /dev/fd/1, a link to /proc/self/fd/1): an open file of this process, written through that very
    descriptor (its offset shared with the shell's redirection), never replaced. None otherwise."""
    own = (f"/proc/{os.getpid()}/fd/", "/proc/self/fd/")
    cur = os.path.abspath(p)
    for _ in range(40):  # the kernel's own limit on a chain of links
        cur = os.path.join(os.path.realpath(os.path.dirname(cur)), os.path.basename(cur))  # /dev/fd -> /proc/PID/fd
        for prefix in own:
            if cur.startswith(prefix) and cur[len(prefix):].isdigit():
                return int(cur[len(prefix):])
        if not os.path.islink(cur):
            return None
        cur = os.path.normpath(os.path.join(os.path.dirname(cur), os.readlink(cur)))
    return None


def _classify(p: Path, what: str):
    """The file to replace atomically (a Path: `p`, or a symlink's regular target) or "through" (a
    character device, FIFO, or a link to this process's descriptor: written through, never replaced). Anything
    else (a folder, a dangling link, a socket, a block device): one-line QmtInputError."""
    try:
        lst = os.lstat(p)
    except (FileNotFoundError, NotADirectoryError):
        return p  # a new file (a file in the way of its folder is named when the folder is made)
    except OSError as exc:  # a path through a file (ENOTDIR), too long, no permission
        raise QmtInputError(f"{what} {p}: {exc.strerror}; choose another path") from None
    try:
        st = os.stat(p)  # follows a symlink
    except OSError as exc:
        raise QmtInputError(f"{what} {p} is a symlink to {os.readlink(p)!r}, which cannot be opened "
                            f"({exc.strerror}); remove the link or choose another path") from None
    if stat.S_ISDIR(st.st_mode):
        raise QmtInputError(f"{what} {p} is a directory; give a file name inside it")
    if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
        return "through"
    if not stat.S_ISREG(st.st_mode):
        raise QmtInputError(f"{what} {p} is a socket or block device, not a file; choose another path")
    if stat.S_ISLNK(lst.st_mode):
        # a link to this process's descriptor (stdout redirected to a file) is written through it; any
        # other link keeps pointing at its target, which is replaced atomically.
        return "through" if _own_fd(p) is not None else Path(os.path.realpath(p))
    return p


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _umask()  # read once at import: os.umask is process-wide, and only a setter


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write `data` to `path` as write_text_atomic does ('-' is stdout)."""
    if is_stdout(path):
        sys.stdout.flush()
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()
        return
    try:
        with atomic_output(path) as tmp:
            if tmp is None:
                return _write_through(Path(path), data)
            tmp.write_bytes(data)
    except OSError as exc:  # a full disk, a quota: one line, the temporary already removed
        raise QmtInputError(f"output {path}: cannot write ({exc.strerror}); free space or choose another "
                            "path") from None


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write `text` to `path` so that a crash never leaves half a file: into a temporary file of an
    unpredictable name created exclusively in the target's folder (mkstemp: O_EXCL, a planted
    symlink is never followed), then renamed over `path`; the temporary is removed on any failure.
    '-' is stdout. A character device or FIFO (/dev/null, a pipe) and a link to this process's own
    descriptor (/dev/stdout, /dev/fd/N) are written through, never replaced by a regular file; a symlink to a regular file
    stays a symlink (its target is replaced). A folder, an unwritable folder, a dangling link:
    one-line QmtInputError."""
    if is_stdout(path):
        sys.stdout.write(text)
        sys.stdout.flush()
        return
    write_bytes_atomic(path, text.encode())


def _write_through(p: Path, data: bytes) -> None:
    """Open an existing device node, FIFO or /proc link (no create, no truncate: a redirected stdout
    keeps what it had) and write `data`; this process's own descriptor (/dev/stdout) is written as it
    is. A FIFO nobody reads is one line, not a hang (O_NONBLOCK open)."""
    fd = _own_fd(p)
    if fd is not None:
        for stream in (sys.stdout, sys.stderr):  # what Python buffered for it goes first
            try:
                same = stream is not None and not stream.closed and stream.fileno() == fd
            except (OSError, ValueError, AttributeError):  # a stream without a descriptor (captured)
                same = False
            if same:
                stream.flush()
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        return
    try:
        fd = os.open(p, os.O_WRONLY | os.O_APPEND | os.O_NONBLOCK)
    except OSError as exc:
        if exc.errno == errno.ENXIO:
            raise QmtInputError(f"output {p} is a FIFO that nobody reads; start its reader first or choose "
                                "another path") from None
        raise QmtInputError(f"output {p}: cannot open for writing ({exc.strerror}); choose another path") from None
    os.set_blocking(fd, True)  # non-blocking only to open: the write waits for a slow reader
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)


@contextmanager
def atomic_output(path: str | Path, suffix: str = ".tmp"):
    """Yield a temporary Path (mkstemp in the target's folder, `suffix` e.g. '.tmp.png' for a writer
    that picks its format by name) to be written, renamed over `path` on success, removed on any failure.
    Yields None when `path` is a device node, FIFO or /proc link: the caller writes through it then
    (write_bytes_atomic does). One-line QmtInputError for a folder or an unwritable folder."""
    p = Path(path)
    target = _classify(p, "output")
    if target == "through":
        yield None
        return
    folder = target.parent if str(target.parent) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise QmtInputError(f"output {p}: a file is in the way of its folder {folder}; choose another path") from None
    except OSError as exc:
        raise QmtInputError(f"output {p}: cannot create folder {folder} ({exc.strerror}); choose another "
                            "path") from None
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=f".{target.name}.", suffix=suffix)
    except OSError as exc:
        raise QmtInputError(f"output {p}: folder {folder} is not writable ({exc.strerror}); choose another "
                            "path") from None
    tmp = Path(name)
    try:
        try:  # the mode a plain open() would give (mkstemp makes 0600), or the replaced file's
            mode = stat.S_IMODE(os.stat(target).st_mode)
        except FileNotFoundError:
            mode = 0o666 & ~_UMASK
        os.fchmod(fd, mode)
        os.close(fd)
        fd = -1
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        if fd >= 0:
            os.close(fd)
        tmp.unlink(missing_ok=True)
        raise


def jsonable(x):
    """Plain JSON types for nested numpy data (non-finite floats become null)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    return x
