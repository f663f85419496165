"""The package's version (``jointid.__version__``), in a module of its own: a lower layer that names it
(the provenance of an uninstalled checkout) imports this, not the package with its API."""

__version__ = "0.1.0"
