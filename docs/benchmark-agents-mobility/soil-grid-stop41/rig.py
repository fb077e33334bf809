import sys, time, tempfile, pathlib
import numpy as np, yaml
from rover_env.config import TerrainConfig, from_dict, to_dict
from rover_env.soil import load_soil
from rover_env.sim.simulator import RoverSim
tmp = pathlib.Path(tempfile.mkdtemp())
def rig(cell, yaw, backend="plugin"):
    soil = tmp / f"ms-{cell:g}.yaml"
    soil.write_text(yaml.safe_dump({**to_dict(load_soil("mars-sand")), "rut_cell": cell}))
    t = from_dict(TerrainConfig, {"name": "level", "size": [8.0, 4.0], "soil": str(soil)})
    sim = RoverSim(terrain=t, backend=backend)
    sim.reset(-2.0, 0.0, yaw)
    sim.set_speed_targets([3.0] * 4)
    sim.step(4000)
    s = []
    for _ in range(300):
        sim.step(10); s.append(sim.wheel_truth().sinkage)
    s = np.array(s) * 1000
    return s.mean(0), s.std(0)
for cell in [float(c) for c in sys.argv[1].split(",")]:
    for yaw in (0.0, 0.1):
        t0 = time.time(); m, sd = rig(cell, yaw)
        print(f"cell {cell*1000:5.1f} mm yaw {yaw:.2f}: front {m[:2].round(2)} middle {m[2:4].round(2)}±{sd[2:4].round(2)} rear {m[4:].round(2)}±{sd[4:].round(2)} ({time.time()-t0:.0f}s)", flush=True)
