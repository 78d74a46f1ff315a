"""Dense disparity and view separation from a single complex image (docs/dense.md)."""
from psvs.dense.cloud import Cloud, disparity_cloud, write_cloud_ply
from psvs.dense.disparity import DEFAULT, FAST, DenseParams, DenseResult, dense_disparity
from psvs.dense.separate import psnr_db, separate_views

__all__ = ["Cloud", "DEFAULT", "FAST", "DenseParams", "DenseResult", "dense_disparity", "disparity_cloud",
           "psnr_db", "separate_views", "write_cloud_ply"]
