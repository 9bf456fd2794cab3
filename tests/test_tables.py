import numpy as np
import pytest

from precontour.prediction.contour import ReferencePath
from precontour.errors import InputError
from precontour.tables import read_columns, read_trajectory, write_columns


def test_round_trip_full_precision(tmp_path):
    rng = np.random.default_rng(0)
    cols = {"t": np.arange(5) * 1e-3, "X": rng.normal(size=5) * 1e-7, "Y": rng.normal(size=5) * 1e3}
    for suffix in (".csv", ".npz", ".parquet"):
        path = write_columns(tmp_path / f"a{suffix}", cols)
        back = read_columns(path, list(cols))
        for name in cols:
            assert np.array_equal(back[name], cols[name])


def test_file_errors(tmp_path):
    with pytest.raises(InputError, match=r"a\.txt: unsupported file type '\.txt'"):
        read_columns(tmp_path / "a.txt", ["t"])
    with pytest.raises(InputError, match=r"missing\.csv: no such file"):
        read_columns(tmp_path / "missing.csv", ["t"])
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"not parquet")
    with pytest.raises(InputError, match=r"bad\.parquet: cannot read parquet file"):
        read_columns(bad, ["t"])
    with pytest.raises(InputError, match=r"output directory does not exist"):
        write_columns(tmp_path / "nodir" / "out.csv", {"t": np.zeros(2)})
    with pytest.raises(InputError, match=r"unsupported output type '\.xlsx'"):
        write_columns(tmp_path / "out.xlsx", {"t": np.zeros(2)})


def test_non_unit_reference_orientation_names_the_row(tmp_path):
    n = 10
    cols = {"t": np.arange(n) * 1e-3, **{a: np.zeros(n) for a in "XYZAC"},
            "Px": np.zeros(n), "Py": np.zeros(n), "Pz": np.zeros(n),
            "Oi": np.zeros(n), "Oj": np.zeros(n), "Ok": np.ones(n)}
    cols["Ok"][6] = 1.5
    path = write_columns(tmp_path / "t.csv", cols)
    with pytest.raises(InputError, match=r"t\.csv, row 7, field 'O': orientation vector is not unit"):
        read_trajectory(path)


def test_reference_curves_need_samples():
    with pytest.raises(InputError, match="too few samples for the reference curves: 5, need 6"):
        ReferencePath.from_samples(np.arange(5.0), np.zeros((5, 3)), np.tile([0, 0, 1.0], (5, 1)))
