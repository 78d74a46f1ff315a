import pytest


@pytest.fixture
def small_rig():
    """The default optics on a 160 x 120 sensor with 4x pixels (same field): fast renders."""
    from psvs import default_rig
    return default_rig().replace(pixel_pitch_mm=(0.04, 0.04), image_size_px=(160, 120),
                                 principal_point_px=(79.5, 59.5))
