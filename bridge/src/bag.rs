//! rosbag2 directories with MCAP storage (issue 4).
