"""Provides the function codes, one module per family: each code's layouts, framing rules
and meaning together (`bits`, `registers`, `diagnostics`, `files`, `identification`,
`exceptions`), the construct building blocks they are written with (`schema`), the spec
and length rules (`spec`), the work every routine shares (`work`), device codes compiled
from dictionaries (`vendor`), the registry (`registry`) and `dissect()` (`dissect`).

A new function code goes in its family's module: its schema, a `FunctionSpec` in that
module's `SPECS`, and its meaning routine beside them.
"""
