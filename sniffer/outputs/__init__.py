"""Provides what leaves modscope: listings, exports, Parquet tables, MQTT."""
