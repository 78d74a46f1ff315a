"""Every reader of a file the user names says what the path is when it is not a file to read: missing ("not
found"), a folder, or a device ("rig show /dev/null" said "not found"). One mechanism:
psvs.io.text.input_file."""
import pytest

from psvs.io.images import read_grey
from psvs.io.params import load_rig
from psvs.io.points import read_csv_columns
from psvs.io.video import video_frames


@pytest.mark.parametrize("read, what", [(read_grey, "image"), (lambda p: load_rig(p), "rig file"),
                                        (lambda p: read_csv_columns(p, ("u_l",)), "points file"),
                                        (video_frames, "video")])
def test_a_folder_a_device_and_a_missing_path_are_named(tmp_path, read, what):
    with pytest.raises(IsADirectoryError, match=f"^{what} {tmp_path} is a folder, not a file$"):
        read(tmp_path)
    with pytest.raises(ValueError, match=f"^{what} /dev/null is not a regular file"):
        read("/dev/null")
    with pytest.raises(FileNotFoundError, match=f"^{what} not found: {tmp_path / 'none.x'}$"):
        read(tmp_path / "none.x")
