"""Provides the function-code registry under its first name: a facade over
`dissectors.pdu`, where each family module holds its codes' layouts, framing rules and
meaning (`bits`, `registers`, `diagnostics`, `files`, `identification`), and
`dissectors.pdu.registry` collects them.

`FUNCTIONS` is the registry of public codes; a session adds its devices' own codes with
`FUNCTIONS.with_vendor(dictionary.functions)`.
"""

from __future__ import annotations

from dissectors.pdu.diagnostics import DIAGNOSTIC_SUB_FUNCTIONS, SubFunction
from dissectors.pdu.exceptions import (
    EXCEPTION_CODES,
    EXCEPTION_LENGTH,
    EXCEPTION_SCHEMA,
    exception_name,
)
from dissectors.pdu.files import FILE_REFERENCE_TYPE, LAST_FILE_RECORD
from dissectors.pdu.identification import (
    CONFORMITY_LEVELS,
    DEVICE_ID_OBJECTS,
    MEI_CANOPEN,
    MEI_DEVICE_ID,
    MEI_TYPES,
    READ_DEVICE_ID_CODES,
    device_object_name,
)
from dissectors.pdu.registry import (
    FUNCTION_CLASSES,
    PUBLIC,
    Registry,
    function_class,
    function_name,
)
from dissectors.pdu.schema import (
    RAW_SCHEMA,
    Bits,
    BitValues,
    Octets,
    Record,
    Repeat,
    UInt8,
    UInt16,
    Unsigned,
    Words,
    WordValues,
    parse_body,
)
from dissectors.pdu.spec import (
    ECHO_ANSWER,
    IMPOSSIBLE,
    NEED_MORE,
    AnswerRule,
    Buffer,
    FunctionSpec,
    LengthRule,
    Limit,
    Walker,
    counted,
    fixed,
)

FUNCTIONS: Registry = PUBLIC
"""Every public function code modscope knows, by code (without the exception bit)."""

__all__ = [
    "CONFORMITY_LEVELS",
    "DEVICE_ID_OBJECTS",
    "DIAGNOSTIC_SUB_FUNCTIONS",
    "ECHO_ANSWER",
    "EXCEPTION_CODES",
    "EXCEPTION_LENGTH",
    "EXCEPTION_SCHEMA",
    "FILE_REFERENCE_TYPE",
    "FUNCTIONS",
    "FUNCTION_CLASSES",
    "IMPOSSIBLE",
    "LAST_FILE_RECORD",
    "MEI_CANOPEN",
    "MEI_DEVICE_ID",
    "MEI_TYPES",
    "NEED_MORE",
    "RAW_SCHEMA",
    "READ_DEVICE_ID_CODES",
    "AnswerRule",
    "BitValues",
    "Bits",
    "Buffer",
    "FunctionSpec",
    "LengthRule",
    "Limit",
    "Octets",
    "Record",
    "Registry",
    "Repeat",
    "SubFunction",
    "UInt8",
    "UInt16",
    "Unsigned",
    "Walker",
    "WordValues",
    "Words",
    "counted",
    "device_object_name",
    "exception_name",
    "fixed",
    "function_class",
    "function_name",
    "parse_body",
]
