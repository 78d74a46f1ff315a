"""Files psvs reads and writes, each a round trip (docs: every writer has its reader).

- ``params``: rig files (TOML or JSON) <-> :class:`psvs.optics.rig.Rig`; ``acquisition``: a camera's
  acquisition settings in a rig file; ``scene_file``: scene files; ``pipeline_file``: image pipelines.
- ``schema``: the one reader of a table's keys, types and bounds (:func:`psvs.io.schema.read_fields`,
  :func:`psvs.io.schema.check_keys`); ``tomlfile``: reading TOML with errors that name the file, writing
  with tomlkit.
- ``points``: CSV tables of correspondences and triangulated points; ``text``: text files the user named.
- ``images``: images (PNG, JPEG, BMP, TIFF, PNM in; 8-bit PNG and .npz out) with ``image_header`` (an
  image's size from its header, before decoding); ``video``: lossless grey video.
- ``atomic``: writes that leave a file whole or as it was; ``jsonsafe``: values as JSON can hold them.
- ``camera_info``: export for ROS (CameraInfo) and OpenCV (FileStorage); ``telemetry``: live views and
  recordings in Foxglove's formats (WebSocket, MCAP); ``rerun_sink``: the same channels for Rerun (.rrd, its
  web viewer; the optional rerun-sdk).
"""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "acquisition": ["load_acquisition", "write_acquisition"],
        "atomic": ["check_output_folder", "check_writable", "output_batch", "write_atomic"],
        "camera_info": ["write_calibration_files"],
        "image_header": ["FORMATS", "HeaderError", "read_header"],
        "images": ["IMAGE_SUFFIXES", "check_frame_size", "first_repeat", "grey8", "grey8_from_bits", "read_grey",
                   "read_image", "write_npy", "write_npz", "write_png"],
        "jsonsafe": ["json_safe"],
        "params": ["dumps_rig", "load_rig", "rig_digest", "rig_from_dict", "rig_from_text", "rig_path", "rig_template",
                   "rig_to_dict", "save_rig"],
        "pipeline_file": ["load_pipeline"],
        "points": ["MATCH_COLUMNS", "ROW_BYTES", "check_rows_memory", "points_csv_text", "read_csv_columns",
                   "read_matches_csv", "write_points_csv"],
        "scene_file": ["load_scene"],
        "schema": ["Field", "REQUIRED", "check_keys", "read_fields"],
        "rerun_sink": ["RerunSink", "Tee", "import_rerun"],
        "telemetry": ["BASE_FRAME", "CAMERA_FRAME", "FLANGE_FRAME", "TORCH_FRAME", "Telemetry", "parse_endpoint",
                      "url_host"],
        "text": ["read_csv_rows"],
        "tomlfile": ["dumps_toml", "load_table", "load_toml", "parse_text", "single_table"],
        "video": ["DAMAGE", "DamagedVideo", "VIDEO_SUFFIXES", "decoded", "open_capture", "open_video_file",
                  "read_video_frame", "video_frames", "write_video"],
    },
)
