#!/usr/bin/python3
"""Draws unseen-effect cases for the reference-format check: per round one case of each family the
simulated plant can hide without a declared column (random strength, nodes and time constant in the
effect suite's ranges, host/sim/suite/cases.cpp), plus a clean case. Prints ID|FAMILY|EFFECT lines.
With KIND "run-ins": per round one run-in transient of each trigger instead (additive per speed
increase, x friction restarted by every start or change, additive and x friction restarted by
starts from standstill only).
Usage: draw_cases.py SEED [ROUNDS [KIND]]   (python3 standard library only)"""
import random
import sys

rng = random.Random(int(sys.argv[1]))
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 2
B = ["rear_bearing", "front_bearing"]


def bearings():
    return rng.choice([["rear_bearing"], ["front_bearing"], B])


cases = []
if len(sys.argv) > 3 and sys.argv[3] == "run-ins":
    for _ in range(rounds):
        n = bearings(); cases.append(("heat_source_transient/add", f"transient:{rng.uniform(2,6):.1f}W/{rng.randint(10,40)}m@{'+'.join(n)}"))
        n = bearings(); cases.append(("heat_source_transient/mult", f"transient-gain:{rng.uniform(0.2,0.6):.2f}/{rng.randint(10,40)}m@{'+'.join(n)}"))
        n = bearings(); cases.append(("heat_source_transient/add-start", f"transient-start:{rng.uniform(5,20):.1f}W/{rng.randint(10,40)}m@{'+'.join(n)}"))
        n = bearings(); cases.append(("heat_source_transient/mult-start", f"transient-gain-start:{rng.uniform(0.2,0.6):.2f}/{rng.randint(10,40)}m@{'+'.join(n)}"))
    rounds = 0
for _ in range(rounds):
    n = bearings(); cases.append(("heat_source_transient/add", f"transient:{rng.uniform(2,6):.1f}W/{rng.randint(10,40)}m@{'+'.join(n)}"))
    n = bearings(); cases.append(("heat_source_transient/mult", f"transient-gain:{rng.uniform(0.2,0.6):.2f}/{rng.randint(10,40)}m@{'+'.join(n)}"))
    n = bearings(); cases.append(("temperature_dependent_heat/rise", f"temp-heat:{rng.uniform(0.005,0.02):.3f}@{'+'.join(n)}"))
    n = bearings(); cases.append(("temperature_dependent_heat/fall", f"temp-heat:-{rng.uniform(0.005,0.02):.3f}@{'+'.join(n)}"))
    hot, cold = rng.choice([("rear_bearing", "housing"), ("front_bearing", "housing"), ("shaft", "housing")])
    cases.append(("coupled_heat", f"coupled-heat:{rng.uniform(2,6):.1f}@{rng.choice([hot,cold])}/{hot}-{cold}"))
    cases.append(("extra_heat_input/housing", f"speed-heat:{rng.uniform(3,10):.1f}@housing^{rng.randint(1,2)}"))
    cases.append(("extra_heat_input/shaft", f"speed-heat:{rng.uniform(5,15):.1f}@shaft^{rng.randint(1,2)}"))
    cases.append(("sensor_lag", f"sensor-lag:{rng.uniform(2,10):.1f}m@ch{rng.randint(1,3)}"))
    cases.append(("sensor_drift", f"sensor-drift:{rng.choice([-1,1])*rng.uniform(0.005,0.02):.3f}@ch{rng.randint(1,3)}"))
    cases.append(("latent_mass", f"latent:{rng.randint(150,600)*10}/{rng.uniform(1,4):.1f}@{rng.choice(['rear_bearing','housing','front_bearing','shaft'])}"))
    cases.append(("none", ""))
for i, (f, e) in enumerate(cases):
    print(f"{i:02d}|{f}|{e}")
