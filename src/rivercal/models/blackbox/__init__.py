"""The black box: an external program described by a ``model.toml``, templates in, files out.

See :mod:`rivercal.models.blackbox.model` (the run), :mod:`~rivercal.models.blackbox.templates` (the
placeholders), :mod:`~rivercal.models.blackbox.readers` (the output formats),
:mod:`~rivercal.models.blackbox.runs` (the run folders), :mod:`~rivercal.models.blackbox.paths` (where
files may be) and :mod:`~rivercal.models.blackbox.supervisor` (the process that starts and stops the
program); ``docs/model-format.md`` documents the file.
"""

from rivercal.models.blackbox.model import BlackBoxModel, BlackBoxRunError

__all__ = ["BlackBoxModel", "BlackBoxRunError"]
