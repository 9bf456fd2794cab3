"""Former path of :mod:`precontour.linuxcnc.run` (the LinuxCNC harness left the readers'
package); importing it warns and gives that module."""

import sys
import warnings

from ..defaults import FORMER_SPELLINGS_REMOVED_IN
from ..linuxcnc import run as _moved

warnings.warn(f"precontour.toolpath.linuxcnc_run is now precontour.linuxcnc.run; the former path is "
              f"removed in precontour {FORMER_SPELLINGS_REMOVED_IN}", DeprecationWarning,
              stacklevel=2)
sys.modules[__name__] = _moved
