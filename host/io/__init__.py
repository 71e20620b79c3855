"""Files in: bathymetry grids, navigation logs with their sonar side files, multibeam surveys.

One module per format, plus the pieces they share:

=====================  ==========================================================================
module                 what it says
=====================  ==========================================================================
``grids``              :func:`read_grid`: any bathymetry grid file to a :class:`Grid`; ``write_npz``
``netcdf``, ``raster``,  the grid formats (NetCDF; GeoTIFF, ESRI ASCII and GMT native; XYZ soundings)
``xyz``
``navlog``             :func:`read_navlog`, :func:`write_navlog`: the CSV navigation log;
                       ``navlog_report``: what reading one kept, skipped and why
``navlog_sonar``       the navigation log's sonar side file
``navlog_checks``      plausibility of a log and of its records against their map
``csvtable``           CSV cells as numbers and times, errors naming the file line
``sonar``              soundings gridded into one record's patch
``survey``             multibeam surveys as a stream of pings, read by ``kongsberg_all``, ``kmall``
                       and ``gsf`` (``kongsberg_all`` writes ``.all`` too, ``kmall_write`` ``.kmall``);
                       ``kmall_parts``: an MRZ split into partitions joined (files and the live receiver)
``survey_grid``        a grid of soundings (``lost grid``); ``survey_summary``: ``lost survey``
``survey_records``     a survey's pings as the navigation's records (``lost run --survey``), streaming
``simulated``          a scenario's tow as pings, to export in a real format
``uncertainty``        a grid's per-node standard deviation layer: found, checked, its gaps filled
``bag``                BAG grids with their uncertainty layer
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
