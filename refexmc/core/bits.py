"""Bit masks of thrusters: the run loop visits only the thrusters whose bit is set.

``for i in set_bits(mask)`` is not available in numba; the loop is written as::

    m = mask
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1  # clear it

which costs one iteration per set bit and no branch per thruster.
"""

from refexmc._jit import DISABLED

if DISABLED:

    def lowest_bit(mask):
        """Index of the lowest set bit of a non-zero integer."""
        mask = int(mask)  # also numpy integers
        return (mask & -mask).bit_length() - 1

else:
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def lowest_bit(typingctx, mask):
        """Index of the lowest set bit of a non-zero integer (LLVM ``cttz``, one instruction)."""
        if not isinstance(mask, types.Integer):
            return None

        def codegen(context, builder, signature, args):
            return builder.cttz(args[0], ir.Constant(ir.IntType(1), 0))

        return mask(mask), codegen
