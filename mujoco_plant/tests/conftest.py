# The package from this source tree, not an installed copy (as tests/tests/peers/mujoco_plant.rs does).
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
