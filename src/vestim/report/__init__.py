"""Figures and tables for users (PNG, Markdown)."""
