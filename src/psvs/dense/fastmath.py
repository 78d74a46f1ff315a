"""The fast-math flags of psvs's Numba kernels: no NaN or infinity and no signed zero to honour (what lets a
float minimum or select vectorise), and nothing that changes a result's value: no reassociation, no
approximate reciprocal or function, no contraction into fused multiply-adds.

LLVM compiles each loop into several copies (the vector body, its remainder, a scalar copy run when a
run-time check finds the arrays might overlap), and which copy runs can depend on where the heap put the
arrays. With ``fastmath=True`` those copies may round differently (a reassociated sum, vrcp14ps and a Newton
step instead of a division, an FMA in one copy only), so the same image could give disparities a few
1e-7 px apart from one process to another. With these flags every copy computes IEEE float arithmetic in
the source's order, so a map depends on its inputs alone (tests/dense/test_threads.py)."""
from __future__ import annotations

SAFE_MATH = {"nnan", "ninf", "nsz"}
