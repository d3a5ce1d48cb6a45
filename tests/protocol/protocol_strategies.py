"""Hypothesis strategies for protocol messages, built from the generated SPECS."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from jointangle.protocol.codec import encode_message
from jointangle.protocol.messages import SPECS
from jointangle.protocol.spec import FieldSpec, MessageSpec


def field_values(f: FieldSpec) -> st.SearchStrategy[Any]:
    if f.type == "text":
        return st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=f.max)
    if f.type.startswith("char"):
        return st.binary(min_size=f.size, max_size=f.size)
    rng = f.int_range
    assert rng is not None
    return st.integers(*rng)


def messages_of(spec: MessageSpec, max_items: int | None = None) -> st.SearchStrategy[Any]:
    kwargs: dict[str, st.SearchStrategy[Any]] = {f.name: field_values(f) for f in spec.fields}
    if spec.group is not None:
        g = spec.group
        item = st.builds(g.cls, **{f.name: field_values(f) for f in g.fields})
        kwargs[g.name] = st.lists(item, max_size=g.max if max_items is None else max_items).map(
            tuple)
    return st.builds(spec.cls, **kwargs)


any_message = st.sampled_from(SPECS).flatmap(lambda s: messages_of(s, max_items=4))


@st.composite
def frame_streams(draw: st.DrawFn, min_frames: int = 1, max_frames: int = 12) -> list[bytes]:
    """Consecutive frames (seq 0, 1, 2, ...) of random messages."""
    n = draw(st.integers(min_frames, max_frames))
    t0 = draw(st.integers(0, 2**32 - 1))
    return [encode_message(draw(any_message), i + 1, (t0 + 2000 * i) & 0xFFFFFFFF)
            for i in range(n)]
