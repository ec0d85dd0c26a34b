"""Cases: ``case.toml`` plus CSV series, validated at load (layer 2)."""

from rivercal.case.load import Case, available_cases, case_from_dict, load_case, resolve_case_path
from rivercal.case.schema import CaseFile, CaseMeta, EngineSettings, InitialConditions

__all__ = [
    "Case",
    "CaseFile",
    "CaseMeta",
    "EngineSettings",
    "InitialConditions",
    "available_cases",
    "case_from_dict",
    "load_case",
    "resolve_case_path",
]
