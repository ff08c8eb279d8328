"""JSON text from a recording or the network, read as any writer may have written it.

One reader for the MCAP reader, the ground station's telemetry and the rover's commands: a payload that
cannot be read is a ``ValueError`` (``UnicodeDecodeError`` is one), never another exception a caller's
``except ValueError`` would miss.
"""

from __future__ import annotations

import json
from typing import Any

import orjson


def loads_json(data: bytes) -> Any:
    """JSON text to Python: orjson (several times the standard library's speed, the hot path of every
    analysis), and the standard library for what only it reads (``NaN`` / ``Infinity`` literals from
    other writers), so no payload Python can read is called malformed. (orjson reads an integer beyond
    64 bits as a float; our recordings hold none.) ``ValueError`` for text that is not JSON, and for
    arrays or objects nested thousands deep (orjson stops at 1024 levels, the standard library's
    recursion at Python's limit)."""
    try:
        return orjson.loads(data)
    except orjson.JSONDecodeError:
        try:
            # str input skips json's byte-encoding detection
            return json.loads(data.decode("utf-8"))
        except RecursionError as err:
            raise ValueError("JSON nested too deep to read") from err
