"""The raster pass: a small image of the frame for toon bands, band masks, object ids, depth
and the self-similar fill (`render_raster` -> `RasterFrame`), sampled by a z-buffer rasterizer
(`zbuffer`, numba kernels loaded by `hits`; Embree rays in `rays`, the reference)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "RasterFrame": "strokekit.raster.bands",
    "RasterOptions": "strokekit.raster.bands",
    "check_raster_fits": "strokekit.raster.rays",
    "render_raster": "strokekit.raster.bands",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
