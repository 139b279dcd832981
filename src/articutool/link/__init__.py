"""articutool.link."""
