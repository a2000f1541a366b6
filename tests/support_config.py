"""Test helpers of the configuration's sections (fsi/config)."""

import typing

from fsi import config

LAWS: dict[str, type] = {
    typing.get_args(typing.get_type_hints(law)["model"])[0]: law
    for law in typing.get_args(config.Rheology)
    if callable(getattr(law, "mu", None))
}
"""The viscosity laws by their ``fluid.rheology.model`` tag: the schema's options that have a
law μ(s)."""
