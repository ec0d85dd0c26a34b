"""hydrolib-core's file models an export saves, made to save faster and the same files.

hydrolib-core dumps the whole tree below a file model before saving it, a dump its INI writer drops, and saves a
file model once per reference to it; the models here skip both (:func:`_written_without_dump`,
:func:`_forcing_model`).
"""

from __future__ import annotations

import functools
from pathlib import Path

__all__: list[str] = []  # the export's models here are private


def _written_without_dump(base):
    """``base`` (a hydrolib-core INI file model) saved without the dump of its whole tree that the INI writer drops.

    hydrolib-core's file model saves itself as ``self._serialize(self.model_dump(), ...)``, but the INI models'
    ``_serialize`` writes from the model's own fields and ignores that dict. The dump reaches into every file
    model below: the MDU's holds all of them, and the external forcing file's holds the whole forcing file once
    per lateral that refers to it. For Dellen (143 laterals) the two discarded dumps were 21 of the export's
    25 s of processor time; the files written are the same.
    """
    from hydrolib.core.dflowfm.ini.models import INIModel

    class Written(base):
        def _save(self, save_settings) -> None:
            if type(self)._serialize is not INIModel._serialize:  # a writer that may use the dump: keep it
                super()._save(save_settings)
                return
            self._serialize({}, save_settings)

    Written.__name__ = Written.__qualname__ = base.__name__
    return Written


@functools.cache
def _fm_model():
    """hydrolib-core's FMModel (the MDU), saved without the dump it drops (:func:`_written_without_dump`)."""
    from hydrolib.core.dflowfm.mdu.models import FMModel

    return _written_without_dump(FMModel)


@functools.cache
def _ext_model():
    """hydrolib-core's ExtModel, saved without the dump it drops (:func:`_written_without_dump`)."""
    from hydrolib.core.dflowfm.ext.models import ExtModel

    return _written_without_dump(ExtModel)


@functools.cache
def _forcing_model():
    """hydrolib-core's ForcingModel, written once however many boundaries, laterals or structures refer to it.

    hydrolib-core saves a file model at every reference to it in the tree it saves (its ``_save`` hook runs
    once per reference): dommel's ``boundaries.bc``, 35,000 rows that 17 boundaries and laterals refer to,
    was written 17 times over, 15 of the export's 23 s. The content is the same each time, so the second
    and later writes to the same file are skipped (and none dumps the tree it drops,
    :func:`_written_without_dump`).
    """
    from hydrolib.core.dflowfm.bc.models import ForcingModel
    from pydantic import PrivateAttr

    class SharedForcingModel(_written_without_dump(ForcingModel)):
        _written_to: Path | None = PrivateAttr(default=None)

        def _save(self, save_settings) -> None:
            target = self._resolved_filepath
            if target is not None and target == self._written_to:
                return
            super()._save(save_settings)
            self._written_to = target

    return SharedForcingModel
