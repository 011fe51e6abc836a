//! `tilting live --ros2`: the flags handed to the plant, which then is a ROS 2 node as well
//! (`tilting_plant::node` `--ros2`, docs/ros2.md).

use crate::LiveError;
use anyhow::anyhow;

/// The ROS 2 flags of `tilting live`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LiveRos2Args {
    /// The plant is a ROS 2 node too (docs/ros2.md): /<robot>/joint_states,
    /// /<robot>/contact_mode, /rosout, and the arm torque accepted on /<robot>/effort_command
    /// (std_msgs/msg/Float64MultiArray). zenoh (a bare --ros2): rmw_zenoh's conventions; dds:
    /// over DDS for a stock ROS 2 (and /<robot>/robot_description); both
    #[arg(long, value_name = "zenoh|dds|both", num_args = 0..=1, default_missing_value = "zenoh",
          value_parser = |s: &str| s.parse::<tilting_ros2::Route>())]
    pub ros2: Option<tilting_ros2::Route>,
    /// ROS 2 domain id of --ros2 [default: ROS_DOMAIN_ID, else 0]
    #[arg(long, value_name = "0-232", requires = "ros2")]
    pub ros_domain: Option<u32>,
    /// With --ros2 --secure: accept /<robot>/effort_command, which the router's ACL does not
    /// restrict to the controller's certificate (refused without this flag)
    #[arg(long, requires = "ros2")]
    pub ros2_allow_commands: bool,
}

impl LiveRos2Args {
    /// Usage errors: the domain's range, the robot name as a ROS 2 name, and `--secure`
    /// without `--ros2-allow-commands`.
    pub fn check(&self, robot: &str, secure: bool) -> Result<(), LiveError> {
        if self.ros2.is_none() {
            return Ok(());
        }
        let usage = |m: String| LiveError::Usage(anyhow!(m));
        let env = std::env::var("ROS_DOMAIN_ID").ok();
        tilting_ros2::domain_id(self.ros_domain, env.as_deref()).map_err(usage)?;
        tilting_ros2::robot::Topics::new(robot).map_err(usage)?;
        if secure && !self.ros2_allow_commands {
            return Err(usage(
                "--ros2 with --secure: /<robot>/effort_command would accept torques from any \
                 ROS 2 node the router lets in, around the ACL that admits only the \
                 controller's certificate; pass --ros2-allow-commands to accept them anyway"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The plant's flags.
    pub fn plant_args(&self) -> Vec<String> {
        let Some(route) = self.ros2 else {
            return Vec::new();
        };
        // The plant reads ROS_DOMAIN_ID itself (it inherits live's environment).
        let mut v = vec!["--ros2".into(), route.to_string()];
        if let Some(d) = self.ros_domain {
            v.extend(["--ros-domain".into(), d.to_string()]);
        }
        if self.ros2_allow_commands {
            v.push("--ros2-allow-commands".into());
        }
        v
    }
}
