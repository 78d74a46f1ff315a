"""The whole-command reference for ``psvs disparity --depth``'s speed: OpenCV's StereoSGBM 3-way as a user would
run it on a separate stereo pair, in one process: read the two views, compute the disparity (3-way, block 5,
P1 = 8·b², P2 = 32·b², as psvs.dense.evaluate.sgbm_reference), turn it into depth (reprojectImageTo3D with the
pair's Q) and write Z as a float32 .npy.

    python bench/sgbm_depth.py LEFT.png RIGHT.png N_DISPARITIES FOCAL_PX BASELINE_MM OUT.npy

Not psvs's code: only NumPy and OpenCV are imported, as a script of OpenCV's own would.
"""
import sys

import cv2
import numpy as np


def main(left: str, right: str, count: int, f_px: float, b_mm: float, out: str) -> None:
    a, b = cv2.imread(left, cv2.IMREAD_GRAYSCALE), cv2.imread(right, cv2.IMREAD_GRAYSCALE)
    n = max(16, int(np.ceil(count / 16.0) * 16))
    block = 5
    m = cv2.StereoSGBM_create(minDisparity=0, numDisparities=n, blockSize=block, P1=8 * block * block,
                              P2=32 * block * block, disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100,
                              speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    d = m.compute(a, b).astype(np.float32) / 16.0
    h, w = a.shape
    q = np.float64([[1, 0, 0, -w / 2], [0, 1, 0, -h / 2], [0, 0, 0, f_px], [0, 0, 1 / b_mm, 0]])
    z = cv2.reprojectImageTo3D(d, q)[..., 2]
    z[d <= 0] = np.nan
    np.save(out, z.astype(np.float32))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]), sys.argv[6])
