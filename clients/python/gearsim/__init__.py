# SPDX-License-Identifier: MIT
"""Python client of gearsimd, the gear-train simulation service.

    import gearsim
    with gearsim.Client() as c:                  # reads the connection file
        c.load(builtin="pair")
        done = c.advance(time=0.01, on_telemetry=print)
        print(c.state()["energy"])
"""
from .client import EVENT_TYPES, FETCH_CHUNK, PROTOCOL, Client
from .connection import default_connection_file, read_connection_file
from .errors import GearsimError, GearsimTimeout

__version__ = "0.1.0"
__all__ = ["Client", "GearsimError", "GearsimTimeout", "default_connection_file",
           "read_connection_file", "PROTOCOL", "EVENT_TYPES", "FETCH_CHUNK"]
