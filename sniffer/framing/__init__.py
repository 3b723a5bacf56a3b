"""Provides framing and pairing: chunks in; frames, noise and transactions in a columnar
store out."""
