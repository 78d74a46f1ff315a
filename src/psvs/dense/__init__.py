"""Dense disparity and view separation from a single complex image (docs/dense.md)."""
from psvs.dense.cloud import Cloud, disparity_cloud, write_cloud_ply
from psvs.dense.disparity import DenseResult, dense_disparity
from psvs.dense.params import DEFAULT, FAST, DenseParams
from psvs.dense.separate import SeparationParams, psnr_db, separate_views
from psvs.dense.workspace import Workspace

__all__ = ["Cloud", "DEFAULT", "FAST", "DenseParams", "DenseResult", "SeparationParams", "Workspace", "dense_disparity",
           "disparity_cloud", "psnr_db", "separate_views", "write_cloud_ply"]
