"""Tests of sniffer.outputs: listings, exports, Parquet, MQTT."""
