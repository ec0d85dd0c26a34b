"""EPA SWMM 5 through swmm-toolkit: the adapter, the ``.inp`` editor, the output reader and a case converter.

Needs the optional extra ``swmm`` (``pip install rivercal[swmm]``: swmm-toolkit, the EPA SWMM engine).
"""

from rivercal.models.swmm.model import SwmmModel, SwmmRunError

__all__ = ["SwmmModel", "SwmmRunError"]
