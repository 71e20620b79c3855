"""Files in: bathymetry grids, navigation logs with their sonar side files, multibeam surveys.

One module per format, plus the pieces they share:

=====================  ==========================================================================
module                 what it says
=====================  ==========================================================================
``grids``              :func:`read_grid`: any bathymetry grid file to a :class:`Grid`; ``write_npz``
``netcdf``, ``raster``,  the grid formats (NetCDF; GeoTIFF, ESRI ASCII and GMT native; XYZ soundings)
``xyz``
``navlog``             :func:`read_navlog`, :func:`write_navlog`: the CSV navigation log
``navlog_sonar``       the navigation log's sonar side file
``navlog_checks``      plausibility of a log and of its records against their map
``csvtable``           CSV cells as numbers and times, errors naming the file line
``sonar``              soundings gridded into one record's patch
``crs``, ``bounds``,   coordinate reference systems; bounds windows; depth sign and nodata;
``depthsign``,         resampling and gridding that keep holes; whole-file and plausibility checks
``gridding``,
``filecheck``
=====================  ==========================================================================
"""

from __future__ import annotations

from ..grid import Grid
from .crs import utm_crs
from .grids import GRID_SUFFIXES, read_grid, write_npz

__all__ = ["Grid", "GRID_SUFFIXES", "read_grid", "write_npz", "utm_crs"]
