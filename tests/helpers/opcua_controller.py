"""A stand-in for a machine controller's OPC UA server, run as its own process by the tests.

``python -m tests.helpers.opcua_controller <port> <sensor> [<sensor> ...] --axes Z [X ...]``
serves, in namespace 2 with string node ids, a Double variable per sensor, ``rpm``, ``elapsed_s``,
``offset_<axis>`` per axis and ``compensation_t_s``; ``--read-only-axis A`` makes
``offset_A`` refuse writes. Prints ``ready`` once it listens, and runs until killed.
"""

from __future__ import annotations

import argparse
import asyncio
import sys

from asyncua import Server, ua

NAMESPACE_URI = "urn:thermal-error-pipeline:test-controller"


async def serve(port: int, sensors: list[str], axes: list[str], read_only: list[str]) -> None:
    """Serve the nodes on 127.0.0.1:``port`` until cancelled."""
    server = Server()
    await server.init()
    server.set_endpoint(f"opc.tcp://127.0.0.1:{port}/controller")
    server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
    index = await server.register_namespace(NAMESPACE_URI)
    machine = await server.nodes.objects.add_object(ua.NodeId("machine", index), "machine")
    names = [*sensors, "rpm", "elapsed_s", *(f"offset_{a}" for a in axes), "compensation_t_s"]
    for name in names:
        node = await machine.add_variable(
            ua.NodeId(name, index), name, ua.Variant(0.0, ua.VariantType.Double)
        )
        if not (name.startswith("offset_") and name.removeprefix("offset_") in read_only):
            await node.set_writable()
    async with server:
        sys.stdout.write(f"ready ns={index}\n")
        sys.stdout.flush()
        while True:
            await asyncio.sleep(3600)


def main() -> None:
    """Parse the arguments and serve."""
    parser = argparse.ArgumentParser()
    parser.add_argument("port", type=int)
    parser.add_argument("sensors", nargs="+")
    parser.add_argument("--axes", nargs="+", default=["Z"])
    parser.add_argument("--read-only-axis", action="append", default=[])
    args = parser.parse_args()
    asyncio.run(serve(args.port, args.sensors, args.axes, args.read_only_axis))


if __name__ == "__main__":
    main()
