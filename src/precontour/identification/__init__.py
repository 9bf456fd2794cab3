"""Identification: the drives' closed loops (and physical parameters) from servo logs.

    servo_log.py        servo logs in: CSV/npz/parquet, LinuxCNC halsampler and halscope,
                        the traces of TNCscope, Sinumerik and TwinCAT, any CSV via a column map
    _trace_formats.py   those traces' layouts and channel names
    _log_reading.py     what the log readers share: text line by line, the columns' names
    tf_fit.py           closed-loop x/X per axis: discrete output-error fit, Tustin to continuous
    physical.py         J, B and friction per direction from motor currents
    identify.py         log + base machine -> identified machine file (controller type ``tf``)
    excitation.py       the identification motion for ``precontour excite``
"""

from .excitation import excitation_trajectory, write_excitation
from .identify import IdentificationResult, identify
from .physical import PhysicalParameters, identify_physical
from .servo_log import FORMATS, ServoLog, parse_column_map, read_servo_log
from .tf_fit import AxisIdentification, identify_axis

__all__ = ["AxisIdentification", "FORMATS", "IdentificationResult", "PhysicalParameters",
           "ServoLog", "excitation_trajectory", "identify", "identify_axis", "identify_physical",
           "parse_column_map", "read_servo_log", "write_excitation"]
