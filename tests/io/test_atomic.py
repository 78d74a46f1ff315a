import os
import stat

import pytest

from psvs.io.atomic import write_atomic


def test_written_file_has_the_usual_permissions(tmp_path):
    path = tmp_path / "out.txt"
    write_atomic(path, "hello")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
    assert path.read_text() == "hello"


def test_failure_leaves_the_old_file(tmp_path):
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")
    with pytest.raises(TypeError):
        write_atomic(path, 12345)  # not str or bytes
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]   # no temporary left behind


def test_grey8_and_npy_helpers(tmp_path):
    import numpy as np

    from psvs.io.images import to_grey8, write_npy

    np.testing.assert_array_equal(to_grey8(np.array([-3.0, 0.4, 0.6, 254.5, 300.0])), [0, 0, 1, 254, 255])
    path = tmp_path / "a.npy"
    write_npy(path, np.arange(6, dtype=np.float32).reshape(2, 3))
    back = np.load(path)
    assert back.dtype == np.float32 and back.shape == (2, 3) and back[1, 2] == 5
