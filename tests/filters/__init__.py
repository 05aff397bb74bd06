"""Tests of the generic filter building blocks."""
