"""What a solved run gives a user: `Results`, the CSV and NPZ tables,
summaries of drivers' efforts and joints' loads, and plots.

May import every layer below it (backends, codegen, numeric, io, symbolic,
model); never `symid.api`, `symid.tools` or `symid.cli`.
"""
