"""``rivercal import sobek3``: a SOBEK 3 model (``Flow1D.md1d``) into a case."""

import math
from pathlib import Path
from typing import Annotated

import typer

from rivercal._format import plural
from rivercal.cli.common import JsonOpt, QuietOpt, emit_json, guard, out_console
from rivercal.errors import OptionError

__all__ = ["import_sobek3_cmd"]


def _require_tomli_w() -> None:
    try:
        import tomli_w  # noqa: F401
    except ImportError:
        raise ValueError("writing the imported case needs tomli-w: pip install 'rivercal[sobek3]'") from None


@guard
def import_sobek3_cmd(
    model: Annotated[Path, typer.Argument(help="The SOBEK 3 model definition file (Flow1D.md1d).")],
    out: Annotated[Path, typer.Option("--out", help="Case folder to write (case.toml, series, import.md).")],
    allow_partial: Annotated[bool, typer.Option(
        "--allow-partial", help="Write the case even when objects that change the hydraulics were refused "
                                "(they are left out; import.md lists them).")] = False,
    dt: Annotated[float | None, typer.Option(help="Time step of the case, s, at least 0.1 (default: the "
                                                  "model's own TimeStep).")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Convert a SOBEK 3 1D model into a case folder, accounting for every object in import.md."""
    if dt is not None and not (math.isfinite(dt) and dt >= 0.1):
        raise OptionError(f"--dt {dt:g}: the time step must be at least 0.1 s (the case's shortest)", option="--dt")
    _require_tomli_w()
    from rivercal.io.sobek3 import ImportOptions, import_sobek3

    result = import_sobek3(model, out, ImportOptions(allow_partial=allow_partial, dt=dt))
    if as_json:
        emit_json(result.summary)
        return
    if quiet:
        return
    s = result.summary
    kinds = ", ".join(plural(n, k.replace("_", " ")) for k, n in s["structures"].items()) or "no structures"
    parts = [plural(s["branches"], "branch"), plural(s["points"], "point"), plural(s["profiles"], "profile"), kinds,
             plural(s["boundaries"], "boundary"), plural(s["laterals"], "lateral"), plural(s["stations"], "station")]
    out_console.print(f"imported [bold]{model.name}[/] into {out}: {', '.join(parts)}, time step {s['dt_s']:g} s; "
                      f"{s['approximated']} approximated, {s['refused']} refused (see {out / 'import.md'})")
