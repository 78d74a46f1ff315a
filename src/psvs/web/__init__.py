"""The browser UI (psvs serve): FastAPI app, plain JS and canvas."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=["sources"],
    submod_attrs={
        "app": ["create_app"],
        "capture_runner": ["CaptureSetup"],
        "guard": ["Access"],
    },
)
