"""articutool.planning."""
