"""One colour, marker and line style per method, the same in every plot of `bench compare`.

Thirteen methods share a plot: matplotlib's ten-colour cycle gave three pairs the same colour
(told apart only by a dash). Here every method has its own colour *and* marker, and the line
style says the family: solid for ours (`array-*`), dashed for the paper's filters and the
firmware, dotted for the neighbouring methods and the analytical estimates.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import NamedTuple


class Style(NamedTuple):
    colour: str
    marker: str
    line: str


METHOD_STYLES: Mapping[str, Style] = MappingProxyType({
    "analytical": Style("#7f7f7f", "x", ":"),
    "smooth": Style("#bcbd22", "+", ":"),
    "ekf": Style("#1f77b4", "o", "--"),
    "ekf-decorrelated": Style("#17becf", "s", "--"),
    "ukf": Style("#9467bd", "^", "--"),
    "mirror": Style("#8c564b", "v", "--"),
    "firmware": Style("#e377c2", "D", "--"),
    "array-ekf": Style("#d62728", "P", "-"),
    "array-fls": Style("#ff7f0e", "X", "-"),
    "array-rts": Style("#2ca02c", "*", "-"),
    "array-ekf-rom": Style("#000000", "h", "-"),
    "madgwick-array": Style("#7b4173", "<", ":"),
    "incl-kf": Style("#637939", ">", ":"),
})
# Methods added later than this table: colours and markers none of the above uses.
SPARE = (Style("#393b79", "p", "-."), Style("#e7ba52", "d", "-."), Style("#843c39", "1", "-."),
         Style("#5254a3", "2", "-."), Style("#8ca252", "3", "-."), Style("#bd9e39", "4", "-."))


def method_styles(methods: Sequence[str]) -> dict[str, Style]:
    """Each method's style: its own from METHOD_STYLES, else the next spare one."""
    spare = iter(SPARE * (1 + len(methods) // len(SPARE)))
    return {m: METHOD_STYLES[m] if m in METHOD_STYLES else next(spare) for m in methods}
