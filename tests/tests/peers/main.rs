//! Our nodes with other peers: the Python controller and plant of `examples/python`, the
//! MuJoCo plant, ROS 2 (raw zenoh, rosbags, rclpy over DDS, pyzeros over rmw_zenoh), Foxglove
//! clients (Python and npm), `tilting echo`/`hz`, an outside peer publishing garbage, and a
//! subscriber that stops reading. An area of the one process test binary (`tests/process.rs`,
//! issue 30); each module was a test file of its own.
//!
//! They run side by side on threads of one process. Robot names carry their test's tag
//! (`robot(tag)`, distinct across the modules), ports are reserved per run (`free_port`), the
//! DDS tests keep their own domain, and no module changes the environment or the working
//! directory. Every test that runs a loop takes `realtime_turn()` first, so no two run at once.
//! A test whose Python package or tool is missing prints SKIP, and fails under
//! `TILTING_NO_SKIP=1` (what `.ci/run` sets).

mod foxglove;
mod garbage;
mod mujoco_plant;
mod python_peer;
mod python_plant;
mod ros2;
mod ros2_clients;
mod slow_subscriber;
mod topics;
