"""Provides device dictionaries: what the registers, coils and inputs of a model mean.

Load a TOML dictionary (docs/dictionaries.md), a bus file, or import Home Assistant
`modbus:` YAML or a CSV register list; decode read or written words into named values.
"""

from __future__ import annotations

from .bus import Bus, UnitBinding, load_bus, parse_unit_binding
from .describe import describe
from .device import DeviceDictionary, Window
from .errors import DictionaryError
from .imports_csv import import_csv
from .imports_ha import import_home_assistant
from .loader import (
    builtin_models,
    check_dictionary,
    file_format,
    load_dictionaries,
    load_dictionary,
    load_model,
)
from .model import (
    TABLES,
    Entry,
    FlagBit,
    Parameter,
    RegisterValue,
    Space,
    Timing,
    ValueSpec,
    canonical_table,
)
from .vendor import FieldsDecoded, FieldValue, ReportServerId, VendorField, VendorFunction

__all__ = [
    "TABLES",
    "Bus",
    "DeviceDictionary",
    "DictionaryError",
    "Entry",
    "FieldValue",
    "FieldsDecoded",
    "FlagBit",
    "Parameter",
    "RegisterValue",
    "ReportServerId",
    "Space",
    "Timing",
    "UnitBinding",
    "ValueSpec",
    "VendorField",
    "VendorFunction",
    "Window",
    "builtin_models",
    "canonical_table",
    "check_dictionary",
    "describe",
    "file_format",
    "import_csv",
    "import_home_assistant",
    "load_bus",
    "load_dictionaries",
    "load_dictionary",
    "load_model",
    "parse_unit_binding",
]
