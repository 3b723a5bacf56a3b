"""Tests of sniffer.analysis: statistics, the poll cycle, gateways, diff, drafts."""
