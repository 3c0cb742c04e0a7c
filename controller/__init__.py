"""Placeholder package (see DESIGN.md §1); filled by later issues."""
