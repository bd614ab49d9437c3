"""The helper process of :mod:`tmm_core.compiled.ahead`: ``python -m tmm_core.compiled`` reads a
pickled list of ``(kernel name, numba signature)`` on its standard input and compiles each kernel
for its signature into numba's on-disk cache (:func:`tmm_core.compiled.binding.compile_requests`).
It ends with the process that started it.
"""
import pickle
import sys

from .ahead import follow_parent
from .binding import compile_requests

follow_parent()
compile_requests(pickle.load(sys.stdin.buffer))
