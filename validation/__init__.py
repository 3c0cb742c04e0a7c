"""Identification, validation against the FEM reference, and reproductions of the paper's studies."""
