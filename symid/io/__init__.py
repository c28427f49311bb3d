"""Reading mechanism files and writing results."""
