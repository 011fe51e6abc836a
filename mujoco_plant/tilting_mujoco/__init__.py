"""The tilting robot in MuJoCo, as a plant node of the tilting control loop (docs/mujoco.md).

- `params`: the robot's parameters, from the same TOML as the Rust workspace (docs/model.md);
- `model`: the MJCF built from them, the contact presets, and `MujocoPlant` (one control period
  under a held torque, the contact mode from the plate's contact forces, divergence checks);
- `wire`: the bytes, keys and session of docs/protocol.md (copied from examples/python/plant.py);
- `node`: the plant node (real time at absolute deadlines, or lockstep) and its command line;
- `checks`: physical self-checks (`python3 -m tilting_mujoco --self-test`, and pytest).
"""

__version__ = "0.1.0"
