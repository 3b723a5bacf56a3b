"""Builds modscope's optional compiled core (sniffer/_core.c); all metadata is in
pyproject.toml. Where the extension cannot be built (no C compiler, no Python headers)
the install still succeeds and the pure-Python core runs (see sniffer/core.py)."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "sniffer._core",
            sources=["sniffer/_core.c"],
            # no fused multiply-add: the framer's times must round as Python's do
            extra_compile_args=["-O2", "-ffp-contract=off"],
            optional=True,
        )
    ]
)
