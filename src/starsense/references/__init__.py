"""Published numbers, one module per source, read by the report and the tests alike."""
