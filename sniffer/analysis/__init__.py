"""Provides analyses over stored rows: statistics, poll cycle, line speed, gateways, diff,
dictionary drafts."""
