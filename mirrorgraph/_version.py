"""The package's version, in a module of its own: the modules that write it into their
output (``calibration.json``, exported camera files, a rig's calibration) import it from
here instead of from the package ``__init__`` above them."""

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("mirrorgraph")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.1.0+src"

__all__ = ["__version__"]
