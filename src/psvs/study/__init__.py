"""Monte-Carlo tolerancing of a PSVS build (docs/tolerancing.md): the TOL.toml format
(:mod:`psvs.study.tolerances`), one sample -- a drawn build, rendered, calibrated from the nominal design as
``psvs calibrate`` does, and scored (:mod:`psvs.study.sample`) -- and the study's report
(:mod:`psvs.study.report`). Plain, picklable, deterministic Python: a runner (Dask or a loop) calls
:func:`psvs.study.sample.run_sample` once per (seed, index)."""
