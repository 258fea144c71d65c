//! Interior-magnet PMSM (placeholder, replaced by the IPM implementation).
/// Placeholder.
#[derive(Clone, Debug, Default)]
pub struct PmsmIpm;
