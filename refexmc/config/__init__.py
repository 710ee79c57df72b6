"""YAML -> validated schema -> the arrays the core takes."""

from refexmc.config.errors import ConfigError

__all__ = ["ConfigError"]
