"""The Bayesian posterior as a file: ``posterior.nc`` (arviz InferenceData, NetCDF via h5netcdf).

Identification does not write files (`workbench.identify.bayes`); the command line writes these
bytes through `workbench.io.outputs.write_outputs` beside ``identification.json``, all files or none.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from workbench.identify.bayes import Posterior

__all__ = ["POSTERIOR_FILE", "posterior_netcdf"]

POSTERIOR_FILE = "posterior.nc"


def posterior_netcdf(posterior: Posterior) -> bytes:
    """The content of ``posterior.nc``: ``posterior.idata`` (posterior, sample_stats, observed_data,
    intervals) as NetCDF.
    """
    with tempfile.TemporaryDirectory() as tmp:  # arviz writes NetCDF to a path, not to memory
        path = Path(tmp) / POSTERIOR_FILE
        posterior.idata.to_netcdf(str(path))
        return path.read_bytes()
