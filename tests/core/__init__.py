"""Tests of the compiled core: every compiled loop gives what its Python reference gives."""
