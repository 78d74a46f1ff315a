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
