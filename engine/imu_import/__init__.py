"""Import IMU recordings made by other tools into a Courtside take (docs/imu-import.md).

Readers: :func:`read_generic_csv` (any CSV/TSV with a column map), :func:`read_xsens` (MVNX, MT Manager and
Xsens DOT text exports), :func:`read_ximu3` (x-IMU3 data-logger folders). Each returns
:class:`SensorStream` objects; :func:`assemble` detects units and quaternion layout
(:mod:`engine.imu_import.detect`), converts to g and puts all sensors on one grid as an :class:`ImportedTake`,
whose ``save`` writes the synthesis-input ``.npz``. CLI: ``courtside import-imu`` (:mod:`engine.imu_import.cli`).

Every reader's samples go through the same rules (:mod:`~engine.imu_import.timing`,
:mod:`~engine.imu_import.samples`, :mod:`~engine.imu_import.orientations`, limits in `engine.recording_limits`): a
missing value stays missing (NaN), an impossible one is refused naming the file and line; nothing is invented."""
from engine.imu_import.csv_generic import read_generic_csv
from engine.imu_import.detect import DetectionError, detect_quat_layout, detect_units, layout_scores, quasi_static
from engine.imu_import.take import ImportedTake, SensorStream, assemble
from engine.imu_import.xsens import MVN_DEFAULT_MAP, read_mt_text, read_mvnx, read_xsens, specific_force_from_free
from engine.imu_import.ximu3 import read_ximu3

__all__ = ["DetectionError", "ImportedTake", "MVN_DEFAULT_MAP", "SensorStream", "assemble", "detect_quat_layout",
           "detect_units", "layout_scores", "quasi_static", "read_generic_csv", "read_mt_text", "read_mvnx", "read_xsens",
           "read_ximu3", "specific_force_from_free"]
