"""Where a black box's files may be: inside its model folder or its run folder, nowhere else.

A ``model.toml`` names files relative to one of two folders: template sources relative to the model
folder (``blackbox.folder``, itself inside the folder of ``model.toml``); template targets, restart files
and outputs relative to the run folder (a copy of the model folder). :func:`relative_path` refuses, at
load, a name that is empty, absolute, holds a NUL character or leads out of its folder with ``..``.
:func:`check_tree` refuses a model folder that holds a symbolic link that leads outside it, dangles or
loops, or a file that is neither a regular file nor a folder (a FIFO, a socket, a device): those would
make rivercal read or write outside its folders, or block, when it copies the folder per run.
:func:`copy_tree` makes that copy with the same checks: a link to a file becomes a copy of the file, a link
to a folder a relative link to the same place in the copy (so a link to an enclosing folder no longer
makes the copy recurse). :func:`inside` tells whether a path, its links followed, stays in a folder; the
black box checks every file it reads from or writes into a run folder with it.
"""

from __future__ import annotations

import os
import shutil
import stat
from collections.abc import Iterable
from pathlib import Path, PurePosixPath

__all__ = ["check_tree", "copy_tree", "inside", "kind_of", "real", "relative_path"]


def relative_path(value: str, where: str) -> str:
    """``value`` as a normalised path relative to its folder, or ValueError saying why it cannot be one.

    Parameters
    ----------
    value
        The name as written in ``model.toml``.
    where
        The folder it is relative to, for the message (``the run folder``).
    """
    if "\0" in value:
        raise ValueError(f"{_quote(value)} holds a NUL character")
    if not value.strip():
        raise ValueError("the name is empty")
    if value.startswith(("/", "\\")) or PurePosixPath(value).is_absolute() or (len(value) > 1 and value[1] == ":"):
        raise ValueError(f"{_quote(value)} is an absolute path: give a file in {where}, relative to it")
    parts: list[str] = []
    for part in value.replace("\\", "/").split("/"):
        if part in ("", "."):
            continue
        if part == "..":
            if not parts:
                raise ValueError(f"{_quote(value)} leads out of {where} (..): give a file inside it")
            parts.pop()
        else:
            parts.append(part)
    if not parts:
        raise ValueError(f"{_quote(value)} is {where} itself, not a file in it")
    return "/".join(parts)


def real(path: str | Path) -> Path:
    """The path with every link followed (OSError for a link that dangles or loops)."""
    return Path(os.path.realpath(path, strict=True))


def inside(path: str | Path, root: str | Path) -> bool:
    """Whether ``path`` lies in ``root`` (or is it) once every link is followed; a missing path's parent counts."""
    try:
        target = Path(os.path.realpath(path))
        base = Path(os.path.realpath(root))
    except (OSError, ValueError):
        return False
    return target == base or base in target.parents


def kind_of(path: str | Path) -> str:
    """What a path is, in words, for messages (``a FIFO``, ``a symbolic link that dangles``, ``missing``)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return "missing"
    except OSError as exc:
        return f"unreadable ({exc.strerror})"
    if stat.S_ISLNK(mode):
        try:
            real(path)
        except OSError as exc:
            return "a symbolic link that loops" if exc.errno == 40 else "a symbolic link that dangles"
        return f"a symbolic link to {kind_of(os.path.realpath(path))}"
    if stat.S_ISREG(mode):
        return "a file"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def _entries(folder: Path, skip: Iterable[Path]) -> Iterable[tuple[Path, os.stat_result]]:
    """Every entry below ``folder`` (links not followed), except the folders in ``skip`` and what they hold."""
    skipped = {Path(os.path.realpath(s)) for s in skip}
    stack = [folder]
    while stack:
        here = stack.pop()
        try:
            names = sorted(os.listdir(here))
        except OSError as exc:
            raise ValueError(f"{here}: cannot be listed ({exc.strerror})") from None
        for name in names:
            path = here / name
            try:
                info = os.lstat(path)
            except OSError as exc:
                raise ValueError(f"{path}: cannot be read ({exc.strerror})") from None
            if stat.S_ISDIR(info.st_mode):
                if Path(os.path.realpath(path)) in skipped:
                    continue
                stack.append(path)
            yield path, info


def _link_target(path: Path, root: Path) -> Path:
    """Where a link below ``root`` leads (inside ``root``), or ValueError naming the link and the problem."""
    try:
        target = real(path)
    except OSError as exc:
        what = "loops" if exc.errno == 40 else "dangles (its target does not exist)"
        raise ValueError(f"{path} is a symbolic link that {what}") from None
    if not (target == root or root in target.parents):
        raise ValueError(f"{path} is a symbolic link to {target}, outside the model folder {root}: copy the file "
                         "into the folder instead")
    mode = os.stat(target).st_mode
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise ValueError(f"{path} is a symbolic link to {kind_of(target)}, not to a file or folder")
    return target


def check_tree(folder: str | Path, skip: Iterable[Path] = ()) -> None:
    """ValueError naming the first entry of the model folder that cannot be copied safely (module docstring).

    Parameters
    ----------
    folder
        The model folder.
    skip
        Folders below it left out (the runs folder when it lies inside the model folder).
    """
    root = real(folder)
    for path, info in _entries(root, skip):
        if stat.S_ISLNK(info.st_mode):
            _link_target(path, root)
        elif not (stat.S_ISREG(info.st_mode) or stat.S_ISDIR(info.st_mode)):
            raise ValueError(f"{path} is {kind_of(path)}: a model folder holds files and folders only")


def copy_tree(folder: str | Path, dest: str | Path, *, exclude: Iterable[str] = (), skip: Iterable[Path] = ()) -> None:
    """Copy the model folder to ``dest`` (a new folder) with the checks of :func:`check_tree`.

    Parameters
    ----------
    folder
        The model folder.
    dest
        The run folder to create.
    exclude
        Paths relative to ``folder`` (``/``-separated) not copied (the templates' sources).
    skip
        Folders below ``folder`` left out.

    Raises
    ------
    ValueError
        For a link that leads outside, dangles or loops, or an entry that is no file or folder.
    OSError
        When the copy cannot be written.
    """
    root = real(folder)
    dest = Path(dest)
    excluded = set(exclude)
    os.mkdir(dest)
    for path, info in _entries(root, skip):
        rel = path.relative_to(root)
        if rel.as_posix() in excluded:
            continue
        out = dest / rel
        if stat.S_ISLNK(info.st_mode):
            target = _link_target(path, root)
            if target.is_dir():
                os.symlink(os.path.relpath(dest / target.relative_to(root), out.parent), out)
            else:
                shutil.copy2(target, out)
        elif stat.S_ISDIR(info.st_mode):
            os.mkdir(out)
        elif stat.S_ISREG(info.st_mode):
            shutil.copy2(path, out, follow_symlinks=False)
        else:
            raise ValueError(f"{path} is {kind_of(path)}: a model folder holds files and folders only")


def _quote(text: str, limit: int = 80) -> str:
    """``text`` quoted, shortened to ``limit`` characters."""
    return repr(text if len(text) <= limit else text[:limit] + "…")
