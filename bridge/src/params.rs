//! Parameters a node serves to the middleware's own tools (`ros2 param`, rclpy's
//! `AsyncParameterClient`), without the node knowing the middleware: the node implements
//! [`ParamService`], and the ROS 2 adapter serves it as the standard parameter services
//! (list, get, get types, set, set atomically, describe) of its node.

/// A parameter's value, in the types of ROS 2's `rcl_interfaces/ParameterValue` that
/// mrtwin's parameters use.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// `bool`.
    Bool(bool),
    /// `integer`.
    Integer(i64),
    /// `double`.
    Double(f64),
    /// `string`.
    Text(String),
    /// `double_array`.
    Doubles(Vec<f64>),
    /// `string_array`.
    Texts(Vec<String>),
}

/// What a node serves as parameters.
pub trait ParamService: Send + Sync {
    /// Every parameter a client may read and set, with its present value.
    fn declared(&self) -> Vec<(String, ParamValue)>;
    /// Would setting `name` to `value` be accepted? `Err`: why not (nothing changes).
    fn check(&self, name: &str, value: &ParamValue) -> Result<(), String>;
    /// Set `name` to `value` (checked first); it takes effect at the node's next sample.
    fn set(&self, name: &str, value: &ParamValue) -> Result<(), String>;
}
