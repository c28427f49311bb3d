"""Reading a mechanism file and writing files safely: the reader, which
validates every element against the constraint and force libraries, tabled
motion (CSV tables a driver or load names), the checks that a file is not
silently misread (degrees for radians, a far assembly), and bounded reads and
atomic writes (`files`).

Sits above `symid.symbolic` (it checks types and keys against the family
registries) and below everything numeric; may import `symid.model`,
`symid.symbolic` and the base modules.
"""
