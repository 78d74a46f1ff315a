"""Monte-Carlo tolerancing of a PSVS build (docs/tolerancing.md): the TOL.toml format
(:mod:`psvs.study.tolerances`), one sample -- a drawn build, rendered, calibrated from the nominal design as
``psvs calibrate`` does, and scored (:mod:`psvs.study.sample`) -- and the study's report
(:mod:`psvs.study.report`). Plain, picklable, deterministic Python: a runner (Dask or a loop) calls
:func:`psvs.study.sample.run_sample` once per (seed, index)."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "montecarlo": ["check_study_time", "prepare_study", "run_study"],
        "report": ["summarise"],
        "sample": ["STUDY_TMP_ENV"],
        "tolerances": ["load_tolerances", "tolerances_path"],
    },
)
