"""articutool.bench."""
