"""The segmentation's compiled hot loops: private to :mod:`depthgram.segmentation`.

Each module holds the loops of one algorithm module of the package (``ransac``, ``plane_sums``,
``coplanar``, ...) that no numpy, scipy or OpenCV routine does. The algorithm modules call them
behind their public functions; nothing outside the segmentation imports them.
"""
