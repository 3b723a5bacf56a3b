"""Tests of dissectors/: function codes, envelopes, the registry, device dictionaries."""
