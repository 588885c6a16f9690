"""A driving stack's side of `scengen cosim`, written against SUMO's own traci package only.

    python examples/cosim_client.py PORT                    # SUMO's driver drives the ego
    python examples/cosim_client.py PORT TESTCASE.json complexity   # replay a certificate
    python examples/cosim_client.py PORT --leave-at 2.0     # close the connection at 2 s

A real stack reads the world each step (traci.vehicle.getPosition, ...), decides, and
commands the ego (setSpeed, slowDown, setAcceleration, moveToXY) before asking for the next
step. docs/cosim.md says what each step means.
"""

import json
import math
import sys
from pathlib import Path

import traci

port, rest = int(sys.argv[1]), sys.argv[2:]
poses = []  # the ego's front bumper and heading per step, from a certificate
leave_at = float(rest[1]) if rest[:1] == ["--leave-at"] else math.inf
if len(rest) == 2 and leave_at == math.inf:
    document = json.loads(Path(rest[0]).read_text())
    length = document["ego"]["length"]
    for s in document["certificates"][rest[1]]:  # centre of the car, heading from north
        h = math.radians(s["heading"])
        poses.append(
            (s["x"] + math.sin(h) * length / 2, s["y"] + math.cos(h) * length / 2, s["heading"])
        )

traci.init(port)
traci.setOrder(2)  # scengen is 1: it has moved the other road users when we are asked
step, dt = 0, traci.simulation.getDeltaT()
try:
    while True:
        if step * dt >= leave_at:
            traci.close()
            break
        if 0 < step < len(poses) and "ego" in traci.vehicle.getIDList():
            x, y, heading = poses[step]  # where the ego is after this step
            traci.vehicle.moveToXY("ego", "", -1, x, y, heading, keepRoute=1)
        traci.simulationStep()
        step += 1
except traci.exceptions.FatalTraCIError:  # the run is over: SUMO closed the connection
    print(f"client: SUMO closed the connection after {step} steps")
