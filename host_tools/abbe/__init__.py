"""abbe host tools: measurement import, fitting, tables, simulation, diagnosis.

Units in every file a person reads or writes: positions in mm, linear errors
in um, angles in urad.
"""

__version__ = "0.1.0"
