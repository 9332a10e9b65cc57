"""The public names of the ik5r datapath machinery, re-exported from the modules that define
them (kept for code written against the former single module; new code imports from those):

* :mod:`.expr` pure expression helpers (``add_sub``, ``rshift_round``, ``saturate`` ...);
* :mod:`.ecp5` the ECP5 primitives (``CCU2C`` chains, ``MULT18X18D``);
* :mod:`.datapath` typed stages, chains, the add/subtract mapping and the construction check;
* :mod:`.build` the pipelined and iterative elaborations;
* :mod:`.products` the partial-product multipliers;
* :mod:`.stream_block` the stream block base class.
"""

from __future__ import annotations

from .datapath import (OUTPUT_FIFO_LATENCY, Datapath, Ecp5Adders, GenericAdders,  # noqa: F401
                       SharedStage, Stage, StageKind, adders_for)
from .ecp5 import ECP5_ADD_SUB_MODULE, ecp5_add_sub_verilog  # noqa: F401
from .expr import (add_sub, asr, drop, leading_zeros, rshift_round, saturate,  # noqa: F401
                   select, table_entry)
from .modes import ARCHS, DSPS, PRODUCTS  # noqa: F401
from .products import LIMB_BITS, add_products  # noqa: F401
from .stream_block import StreamBlock, check_common  # noqa: F401

__all__ = ["ARCHS", "DSPS", "PRODUCTS", "LIMB_BITS", "OUTPUT_FIFO_LATENCY", "ECP5_ADD_SUB_MODULE",
           "ecp5_add_sub_verilog", "Datapath", "Stage", "StageKind", "SharedStage",
           "GenericAdders", "Ecp5Adders", "adders_for", "StreamBlock", "check_common", "add_sub",
           "asr", "rshift_round", "saturate", "leading_zeros", "select", "add_products",
           "table_entry", "drop"]
