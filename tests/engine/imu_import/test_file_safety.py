"""Results are written whole or not at all, and never over an input (`engine.atomic_write`, issue 30)."""
from __future__ import annotations

import errno
import os

import numpy as np
import pytest

from engine.atomic_write import atomic_write, refuse_overwriting_inputs
from engine.errors import CourtsideError
from engine.imu_import import ImportedTake


def _disk_full_after(n_bytes: int):
    """A writer that writes ``n_bytes`` and then fails as a full disk does."""
    def write(fh) -> None:
        fh.write(b"x" * n_bytes)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return write


def test_a_failed_write_leaves_the_old_file_and_no_partial_one(tmp_path):
    out = tmp_path / "take.npz"
    out.write_bytes(b"the previous take")
    with pytest.raises(CourtsideError, match=rf"{out}: cannot write \(No space left on device\)"):
        atomic_write(out, _disk_full_after(10_000))
    assert out.read_bytes() == b"the previous take"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.npz"]


def test_an_interrupted_take_save_leaves_nothing(tmp_path, monkeypatch):
    take = ImportedTake(100.0, np.arange(5) / 100.0, np.zeros((5, 1, 3)), ["chest"], ["dev"])

    def killed(fh, **arrays) -> None:
        fh.write(b"PK\x03\x04 half a zip")
        raise KeyboardInterrupt  # a Ctrl-C half-way: not an OSError, and still nothing is left behind

    monkeypatch.setattr(np, "savez_compressed", killed)
    with pytest.raises(KeyboardInterrupt):
        take.save(tmp_path / "take.npz")
    assert list(tmp_path.iterdir()) == []


def test_written_file_is_complete_and_has_a_normal_mode(tmp_path):
    take = ImportedTake(100.0, np.arange(5) / 100.0, np.ones((5, 1, 3)), ["chest"], ["dev"])
    path = take.save(tmp_path / "take.npz")
    with np.load(path, allow_pickle=False) as z:
        np.testing.assert_array_equal(z["acc_g"], np.ones((5, 1, 3)))
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask


def test_an_output_that_is_an_input_is_refused_however_it_is_named(tmp_path):
    rec = tmp_path / "rec"
    (rec / "dev").mkdir(parents=True)
    (rec / "dev" / "Inertial.csv").write_text("t\n")
    take = tmp_path / "t.npz"
    take.write_bytes(b"take")
    (tmp_path / "link.npz").symlink_to(take)
    cases = {tmp_path / "t.npz": take, tmp_path / "." / "t.npz": take, tmp_path / "link.npz": take,
             rec / "dev" / "Inertial.csv": rec}
    for out, given in cases.items():
        with pytest.raises(CourtsideError, match="would overwrite"):
            refuse_overwriting_inputs([out], [given])
    refuse_overwriting_inputs([tmp_path / "t.calibration.json"], [take])  # a new name is fine
