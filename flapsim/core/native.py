"""Tiny numba intrinsics that turn integer addresses into typed pointers.

The compiled passive callback finds its arrays through a table of addresses (see
:mod:`flapsim.core.callbacks`); these casts are all it needs to view them as arrays.
"""

from __future__ import annotations

from numba import types
from numba.core.extending import intrinsic


@intrinsic
def ptr_f64(typingctx, addr):
    """int64 address -> float64*."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return sig, codegen


@intrinsic
def ptr_i64(typingctx, addr):
    """int64 address -> int64*."""
    sig = types.CPointer(types.int64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return sig, codegen


@intrinsic
def voidptr_to_int(typingctx, ptr):
    """void* -> int64 (to compare the mjData* MuJoCo passes with registered addresses)."""
    sig = types.int64(types.voidptr)

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.int64))

    return sig, codegen
