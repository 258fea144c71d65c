//! The measured signal drawn above a plot's outputs for context.

/// A measured signal drawn above the outputs for context, e.g. the mechanical speed
/// `w_m` \[rad/s\]: its name, unit and samples per log (each as long as that log's
/// comparison).
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    /// Name shown on the axis, e.g. `w_m`.
    pub name: &'a str,
    /// Unit shown on the axis, e.g. `rad/s`.
    pub unit: &'a str,
    /// Samples of each log, in the order of the comparisons.
    pub per_log: &'a [&'a [f64]],
}
