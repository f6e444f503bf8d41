"""The toolkit's version, as installed (a module of its own: ``pillar-xval --version`` reads it
without loading the toolkit)."""

from importlib import metadata


def package_version() -> str:
    """The installed distribution's version, or ``"0+unknown"`` for a checkout that was never
    installed."""
    try:
        return metadata.version("pillar-xval")
    except metadata.PackageNotFoundError:
        return "0+unknown"
