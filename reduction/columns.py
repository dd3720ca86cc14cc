"""Column names of an orbit table's per-row arrays: the one place they are spelled.

Light on purpose (no imports): the store's layout and the report's typesetting read them
without loading numpy.
"""

#: order of OrbitTable.gamma2's last axis: (displacement, force) pairs of a coherence
GAMMA2_COLUMNS = ("xfx", "yfx", "xfy", "yfy")
#: order of OrbitTable.u's last axis: the phasors x, y (m), fx, fy (N)
U_COLUMNS = ("x", "y", "fx", "fy")
