"""The jointangle wire protocol, host side.

- `messages` (generated from protocol/messages.toml): constants, enums, dataclasses, SPECS.
- `framing`: COBS + CRC-16 frames and the streaming decoder with damage counters.
- `codec`: message payloads to and from the dataclasses.
- `construct_defs`: the same layout as declarative `construct` definitions.
- `bulk`: the vectorised numpy decoder for recordings (same frames and counts as `framing`).

Importing this package has no side effects.
"""

from jointangle.protocol.codec import decode_message, decode_payload, encode_message
from jointangle.protocol.framing import (
    DecoderStats,
    Frame,
    ProtocolMismatchError,
    StreamDecoder,
    decode_stream,
    encode_frame,
)
from jointangle.protocol.messages import PROTOCOL_VERSION, SCHEMA_HASH

__all__ = [
    "PROTOCOL_VERSION",
    "SCHEMA_HASH",
    "DecoderStats",
    "Frame",
    "ProtocolMismatchError",
    "StreamDecoder",
    "decode_message",
    "decode_payload",
    "decode_stream",
    "encode_frame",
    "encode_message",
]
