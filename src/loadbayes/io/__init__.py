"""Readers, writers and validation of measurement files."""
