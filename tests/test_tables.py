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


def _consistent_columns(machine, n=40):
    """A trajectory whose reference is the direct kinematics of its axes."""
    t = np.arange(n) * 1e-3
    q = np.column_stack([np.linspace(0, 5, n), np.linspace(1, -2, n), np.full(n, 320.0),
                         np.linspace(0.1, 0.4, n), np.linspace(2.5, 3.5, n)])
    P, O = machine.kinematics.forward(q)
    names = ("X", "Y", "Z", "A", "C", "Px", "Py", "Pz", "Oi", "Oj", "Ok")
    return {"t": t, **dict(zip(names, np.column_stack([q, P, O]).T))}


def test_c_wrap_is_unwrapped_with_one_notice(tmp_path, machine, caplog):
    cols = _consistent_columns(machine)
    wrapped = dict(cols, C=np.where(cols["C"] > np.pi, cols["C"] - 2 * np.pi, cols["C"]))
    assert np.abs(np.diff(wrapped["C"])).max() > 6     # a post-processor's wrap into (-pi, pi]
    path = write_columns(tmp_path / "w.csv", wrapped)
    traj = read_trajectory(path, kinematics=machine.kinematics)
    np.testing.assert_allclose(traj.axis("C"), cols["C"], atol=1e-12)
    assert len(caplog.records) == 1 and "w.csv, row" in caplog.text and "unwrapped" in caplog.text


def test_reference_must_match_the_direct_kinematics(tmp_path, machine):
    from precontour.tables import REFERENCE_TOLERANCE
    cols = _consistent_columns(machine)
    read_trajectory(write_columns(tmp_path / "ok.csv", cols), kinematics=machine.kinematics)
    tip, angle = REFERENCE_TOLERANCE
    near = dict(cols, Pz=cols["Pz"] + 0.5 * tip)
    read_trajectory(write_columns(tmp_path / "near.csv", near), kinematics=machine.kinematics)
    off = dict(cols, Pz=cols["Pz"] + np.where(np.arange(40) >= 12, 2 * tip, 0.0))
    with pytest.raises(InputError, match=r"off.csv, row 13, field 'Px': reference tool tip is "
                                         r"0.02 mm from the direct kinematics"):
        read_trajectory(write_columns(tmp_path / "off.csv", off), kinematics=machine.kinematics)
    turned = dict(cols, Oi=cols["Oi"] + 3 * angle)
    with pytest.raises(InputError, match=r"field 'Oi': reference orientation is"):
        read_trajectory(write_columns(tmp_path / "turned.csv", turned),
                        kinematics=machine.kinematics)


def test_csv_header_with_bom_and_quotes(tmp_path):
    path = tmp_path / "b.csv"
    path.write_bytes(b'\xef\xbb\xbf"t", X\n0,1\n0.001,2\n')
    cols = read_columns(path, ["t", "X"])
    np.testing.assert_array_equal(cols["X"], [1.0, 2.0])


def test_parquet_text_column_names_the_row(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    path = tmp_path / "s.parquet"
    pq.write_table(pa.table({"t": [0.0, 1.0, 2.0], "X": ["1", "2", "x"]}), path)
    with pytest.raises(InputError, match=r"s.parquet, row 3, field 'X': not a number: 'x'$"):
        read_columns(path, ["t", "X"])
