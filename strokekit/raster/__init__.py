"""The raster pass: a small image of the frame for toon bands, band masks, object ids, depth
and the self-similar fill (`render_raster` -> `RasterFrame`), sampled by a z-buffer rasterizer
(`zbuffer`, numba kernels loaded by `hits`; Embree rays in `rays`, the reference)."""

from strokekit.raster.bands import RasterFrame, RasterOptions, render_raster
from strokekit.raster.rays import check_raster_fits

__all__ = ["RasterFrame", "RasterOptions", "check_raster_fits", "render_raster"]
