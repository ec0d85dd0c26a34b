"""One door to every model: a case (folder or packaged name) or a ``model.toml`` of an adapter.

:func:`load_model` takes a case folder (with ``case.toml``), a packaged case name, a ``model.toml`` (or
a folder that holds one, or the name of a packaged model folder) and returns the model. The adapters of
``model.toml`` are imported only when a file asks for them, so SWMM and BMI stay optional.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from rivercal._time import Windows
from rivercal.case.load import CASE_FILE, available_cases
from rivercal.errors import CaseError
from rivercal.models.config import MODEL_FILE, ModelFile, ModelFileError, read_model_file
from rivercal.models.contract import CalibrationSetup
from rivercal.models.embedded import load_case_model

__all__ = ["available_models", "load_model", "load_model_file", "model_file_path", "model_source"]


def available_models() -> list[str]:
    """Names of the packaged folders with a ``model.toml`` (next to the packaged cases)."""
    base = resources.files("rivercal.cases")
    return sorted(p.name for p in base.iterdir() if p.is_dir() and (p / MODEL_FILE).is_file())


def model_file_path(source: str | Path) -> Path | None:
    """The ``model.toml`` that ``source`` names (a file, a folder holding one, a packaged name), else None."""
    path = Path(source)
    if path.is_file() and path.suffix == ".toml" and path.name != CASE_FILE:
        return path
    if path.is_dir() and (path / MODEL_FILE).is_file() and not (path / CASE_FILE).is_file():
        return path / MODEL_FILE
    name = str(source)
    if not path.exists() and name in available_models() and name not in available_cases():
        return Path(str(resources.files("rivercal.cases") / name / MODEL_FILE))
    return None


def model_source(source: str | Path) -> str | None:
    """Where a model given to :func:`load_model` lies: an absolute path, or None for a packaged name.

    A run records it, so that a report or the dashboard can open the model again.
    """
    path = Path(source)
    return str(path.resolve()) if path.exists() else None


def load_model(source: str | Path) -> Any:
    """The model of a case folder, a packaged case name, or a ``model.toml`` (or a folder holding one).

    Raises
    ------
    CaseError
        For a bad case, or (as :class:`~rivercal.models.config.ModelFileError`) a bad ``model.toml``;
        the message names the file, the field and the problem.

    Examples
    --------
    >>> from rivercal.models import load_model
    >>> sim = load_model("dommel")
    >>> sim.observables[:2]
    ['0028.h_up', '0028.h_down']
    """
    path = model_file_path(source)
    if path is not None:
        return load_model_file(path)
    if not Path(source).exists() and str(source) not in available_cases():  # name the packaged models too
        raise CaseError(f"{str(source)!r} is neither a case folder nor a packaged case, nor a model.toml or a packaged "
                        f"model (packaged cases: {', '.join(available_cases())}; packaged models: "
                        f"{', '.join(available_models())})")
    return load_case_model(source)


def load_model_file(path: str | Path) -> Any:
    """Build the adapter a ``model.toml`` describes.

    Raises
    ------
    ModelFileError
        For a bad file or a referenced file that is missing or wrong, naming the file and the field.
    """
    path = Path(path)
    spec = read_model_file(path)
    root = path.parent
    label = str(path)
    windows = Windows({w.name: (w.start, w.end) for w in spec.windows}, f"model {spec.model.name}")
    setup = CalibrationSetup(parameters=tuple(spec.parameters), windows=windows,
                             algorithm=spec.calibration.algorithm, options=dict(spec.calibration.options))
    try:
        model = _build(spec, root, setup)
    except ModelFileError:
        raise
    except ImportError as exc:
        extra = {"swmm": "swmm", "bmi": "bmi"}.get(spec.model.kind, "")
        raise ModelFileError(f"the {spec.model.kind} adapter needs a package that is not installed ({exc}); "
                             f"install rivercal[{extra}]", file=label, field="model.kind") from None
    except (ValueError, KeyError, OSError) as exc:
        raise ModelFileError(_one_line(exc), file=label, field=spec.model.kind) from None
    from rivercal.models.contract import check_parameters

    try:
        check_parameters(model, spec.parameters)
    except ValueError as exc:
        raise ModelFileError(str(exc), file=label, field="parameters") from None
    return model


def _build(spec: ModelFile, root: Path, setup: CalibrationSetup) -> Any:
    meta = spec.model
    if meta.kind == "swmm":
        from rivercal.models.swmm.model import SwmmModel

        inp = root / spec.swmm.inp  # type: ignore[union-attr]
        if not inp.is_file():
            raise ModelFileError(f"no such file {inp}", file=str(root / MODEL_FILE), field="swmm.inp")
        return SwmmModel(inp, spec.swmm.stations, name=meta.name, start=meta.start, end=meta.end,  # type: ignore[union-attr]
                         output_interval=meta.output_interval, spinup=meta.spinup, calibration=setup)
    if meta.kind == "blackbox":
        from rivercal.models.blackbox import BlackBoxModel

        return BlackBoxModel(spec, root, calibration=setup)
    from rivercal.models.bmi.adapter import BmiModel

    return BmiModel.from_spec(spec, root, calibration=setup)


def _one_line(exc: BaseException) -> str:
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    return " ".join(str(text).split())
