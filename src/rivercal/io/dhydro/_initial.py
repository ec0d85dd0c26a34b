"""The initial state of a D-Flow FM model as case ``[initial]`` and ``branches[].initial_levels``.

It comes from the initial-field file's 1dField water depth or level (global and per branch), else from the MDU's
``WaterLevIni``.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from rivercal.io.dhydro._context import Context, _numbers
from rivercal.io.dhydro._source import is_file


def _initial(ctx: Context) -> None:
    """``[initial]`` from the initial-field file (1dField water depth or level) or the MDU's WaterLevIni."""
    fm = ctx.model.fm
    sources = ctx.model.sources
    initial: dict = {"depth": 0.0}
    level_ini = getattr(fm.geometry, "waterlevini", None)
    found = False
    path = _ini_field_path(ctx)
    index = _readable(ctx, path, "initial fields", f"{ctx.model.mdu.name}, iniFieldFile") if path is not None else None
    for section in (index.sections if index is not None else []):
        header = section.header.lower()
        if header == "general":
            continue
        quantity = (section.value("quantity") or "?").lower()
        where = f"{sources.rel(index.path)}, line {section.line}"
        if header == "parameter":
            ctx.ledger.refused("initial field", f"{quantity} ({where})", "a [Parameter] field (a spatially varying "
                               "model parameter) is not read", hydraulic=True)
            continue
        if header != "initial":
            ctx.ledger.warn(f"{where}: a [{section.header}] block in an initial-field file is not read")
            continue
        if quantity not in ("waterdepth", "waterlevel"):
            ctx.ledger.refused("initial field", quantity, "only the initial water depth or level is used",
                               hydraulic=False)
            continue
        kind = (section.value("dataFileType") or "").lower()
        if kind != "1dfield":
            ctx.ledger.refused("initial field", quantity, f"data file type {kind!r} (2D samples or polygons) is not "
                               "read; the initial state comes from the other settings", hydraulic=False)
            continue
        name = section.value("dataFile")
        if not name:
            ctx.ledger.error(where, f"[Initial] {quantity}: no dataFile")
            continue
        data = _readable(ctx, _relative(ctx, Path(name), index.path), f"initial {quantity}",
                         f"{where}, dataFile = {name}")
        if data is None:
            continue
        glob, per_branch = _one_d_field(ctx, data)
        if glob is None and not per_branch:
            ctx.ledger.exact("initial field", quantity, f"{sources.rel(data.path)} holds no [Global] value and no "
                             "[Branch] values: D-Flow FM applies none either, and the initial state comes from the MDU")
            continue
        if glob is not None:
            if quantity == "waterdepth" and glob < 0:
                ctx.ledger.error(sources.rel(data.path), f"the initial water depth {glob:g} m is negative")
                continue
            initial = {"depth": glob} if quantity == "waterdepth" else {"depth": 0.0, "level": glob}
            found = True
            ctx.ledger.exact("initial field", quantity)
        for branch, (chainages, values, where_branch) in per_branch.items():
            _branch_initial(ctx, quantity, branch, chainages, values, where_branch)
    if not found and level_ini is not None:
        initial = {"depth": 0.0, "level": float(level_ini)}
        ctx.ledger.exact("setting", "WaterLevIni", "initial level where no initial field is given")
    ctx.case["initial"] = initial
    if index is not None:
        ctx.source("initial", "initial", f"{sources.rel(index.path)}")


def _branch_initial(ctx: Context, quantity: str, branch: str, chainages: list[float], values: list[float],
                    where: str) -> None:
    """A [Branch] block of an initial field as the branch's ``initial_levels``.

    Levels are taken as they are (exact); a depth is added to the bed level interpolated between the
    cross-sections at every chainage where either changes slope (approximated: D-Flow FM adds it to the bed level
    of each calculation point, the lowest of its links).
    """
    what = f"{quantity} on {branch}"
    target = None
    if ctx.ids.get("branch") is not None and ctx.ids["branch"].known(branch):
        target = next((b for b in ctx.case["branches"] if b["id"] == ctx.id("branch", branch)), None)
    if target is None:
        ctx.ledger.refused("initial field", what, f"{where}: the branch is not in the network", hydraulic=False)
        return
    if quantity == "waterlevel":
        target["initial_levels"] = {"chainages": chainages, "levels": values}
        ctx.ledger.exact("initial field", what, "initial levels along the branch (branches[].initial_levels)")
        return
    if any(v < 0 for v in values):
        ctx.ledger.error(where, f"[Branch] {branch!r}: a negative initial water depth")
        return
    cs = target["cross_sections"]
    ch = [c["chainage"] for c in cs]
    beds = [c["bed_level"] for c in cs]
    at = sorted({*chainages, *ch, 0.0, float(target["length"])})
    target["initial_levels"] = {"chainages": at, "levels": [float(np.interp(c, ch, beds) + np.interp(c, chainages,
                                                                                                       values))
                                                            for c in at]}
    ctx.ledger.approximated("initial field", what, "initial depths along the branch become initial levels: the depth "
                            "plus the bed level interpolated between the cross-sections (D-Flow FM adds it to the bed "
                            "level of each calculation point, the lowest of its links; affects the first hours only)")


def _ini_field_path(ctx: Context) -> Path | None:
    from rivercal.io.dhydro._mdu import _dropped_paths

    if ("geometry", "inifieldfile") in ctx.model.sources.dropped:
        found = _dropped_paths(ctx.model.sources.ini(ctx.model.mdu), "geometry", "inifieldfile")
        return _relative(ctx, found[0], ctx.model.mdu) if found else None
    ini = ctx.model.fm.geometry.inifieldfile
    name = getattr(ini, "filepath", None)
    return None if name is None else _relative(ctx, Path(name), ctx.model.mdu)


def _relative(ctx: Context, path: Path, referring: Path) -> Path:
    """A file name as D-Flow FM resolves it: relative to the MDU's folder, or to its own file's folder."""
    if path.is_absolute():
        return path
    if bool(getattr(ctx.model.fm.general, "pathsrelativetoparent", False)):
        return referring.parent / path
    return ctx.model.mdu.parent / path


def _readable(ctx: Context, path: Path, what: str, named_at: str):
    """The line index of a file the initial state needs, or a refusal saying why not and where the file is named."""
    sources = ctx.model.sources
    reason = None
    if not sources.inside(path):
        reason = f"it lies outside the model folder {sources.root} (the import reads no file outside it)"
    elif not is_file(path):
        reason = "the file does not exist"
    if reason is None:
        try:
            index = sources.ini(path)
        except OSError as exc:
            reason = f"the file cannot be read ({exc.strerror or exc})"
        else:
            if not index.sections:
                reason = "not a D-Flow FM INI file (no [section])"
            else:
                for line, text in index.stray[:5]:
                    ctx.ledger.error(f"{sources.rel(path)}, line {line}", f"{text[:60]!r} is not INI text")
                return index
    ctx.ledger.refused("file", sources.rel(path), f"named at {named_at}: {reason}; the {what} it holds are missing, "
                       "which changes the initial state", hydraulic=True)
    return None


def _one_d_field(ctx: Context, index) -> tuple[float | None, dict[str, tuple[list[float], list[float], str]]]:
    """The [Global] value and, per [Branch], its chainages, values and place of a 1dField file.

    Non-numbers, a count that does not match ``numLocations`` and chainages that go down are errors with their line.
    A branch with ``numLocations = 0`` has one value along it (chainage 0).
    """
    sources = ctx.model.sources
    glob = None
    per_branch: dict[str, tuple[list[float], list[float], str]] = {}
    for section in index.sections:
        header = section.header.lower()
        if header not in ("global", "branch"):
            continue
        raw = section.first("value" if header == "global" else "values")
        if raw is None or raw.value is None:
            ctx.ledger.error(f"{sources.rel(index.path)}, line {section.line}", f"[{section.header}] has no "
                             f"{'value' if header == 'global' else 'values'}")
            continue
        values = _numbers(raw.value)
        if not values or not all(np.isfinite(values)) or any(abs(v) > 1e4 for v in values):
            ctx.ledger.error(f"{sources.rel(index.path)}, line {raw.line}",
                             f"{raw.key} = {raw.value}: not finite numbers of a plausible size")
            continue
        if header == "global":
            glob = values[0]
            continue
        where = f"{sources.rel(index.path)}, line {section.line}"
        count = _numbers(section.value("numLocations") or "0")
        n = int(count[0]) if count and count[0] >= 0 else -1
        chain_raw = section.first("chainage")
        chainages = _numbers(chain_raw.value) if chain_raw is not None and chain_raw.value else []
        if n <= 0:
            chainages, values = [0.0], values[:1]
        if n < 0 or len(chainages) != len(values) or (n > 0 and len(values) != n):
            ctx.ledger.error(where, f"[Branch] {section.value('branchId')!r}: {len(values)} values and "
                             f"{len(chainages)} chainages for numLocations = {section.value('numLocations')}")
            continue
        if not all(np.isfinite(chainages)) or any(b < a for a, b in itertools.pairwise(chainages)) or chainages[0] < 0:
            ctx.ledger.error(f"{sources.rel(index.path)}, line {chain_raw.line if chain_raw else section.line}",
                             f"[Branch] {section.value('branchId')!r}: chainages must be finite, not negative and "
                             "increasing")
            continue
        for i in range(1, len(chainages)):  # a chainage given twice: a step, spread over 1 mm
            if chainages[i] <= chainages[i - 1]:
                chainages[i] = chainages[i - 1] + 0.001
        per_branch[section.value("branchId") or "?"] = (chainages, values, where)
    return glob, per_branch
