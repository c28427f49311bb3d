"""Design studies: many variants of one mechanism (sweeps, samples), their
figures (peak and RMS efforts, peak power, peak joint force) and where they run
(this machine's cores, or a Dask cluster)."""
