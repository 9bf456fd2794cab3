"""Former path of :mod:`precontour.linuxcnc.drives` (the LinuxCNC harness left the readers'
package); importing it warns and gives that module."""

import sys
import warnings

from ..defaults import FORMER_SPELLINGS_REMOVED_IN
from ..linuxcnc import drives as _moved

warnings.warn(f"precontour.toolpath.linuxcnc_drives is now precontour.linuxcnc.drives; the former path is "
              f"removed in precontour {FORMER_SPELLINGS_REMOVED_IN}", DeprecationWarning,
              stacklevel=2)
sys.modules[__name__] = _moved
