"""``Ref``: a tuple of arrays handed to compiled code as one object.

numba unboxes every array argument of a call on its own (about 0.1 us each); a fused step on
free spheres took the schedule state's 9 arrays and the pair set's 7 at every call, about as
long as the step's own work on a small scene. A ``Ref`` is a numba ``StructRef`` holding the
tuple: it unboxes as one pointer, and the arrays stay shared with their Python owners, so every
write is seen on both sides. Build one when the tuple's arrays change (rarely), not per call.
"""

from __future__ import annotations

from numba.core import types
from numba.experimental import structref

__all__ = ["Ref"]


@structref.register
class RefType(types.StructRef):
    """numba's type of a :class:`Ref` (its field's type, literals widened)."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Ref(structref.StructRefProxy):
    """One compiled-code object over ``value`` (a tuple of arrays); kernels read ``ref.value``."""

    def __new__(cls, value: tuple) -> Ref:
        return structref.StructRefProxy.__new__(cls, value)


structref.define_proxy(Ref, RefType, ["value"])
