"""The fuzz harness: bounded Hypothesis runs over every reader, framer and dissector."""
