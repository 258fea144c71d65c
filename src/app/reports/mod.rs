//! The fits of issue 33 asked for by type: a flux map ([`FluxMapRequest`]), the saturated
//! IPM model ([`SaturationRequest`]), locked-rotor logs ([`StandstillRequest`]) and the
//! mechanics ([`MechanicsRequest`]), each run into a [`Report`] (its text, its JSON and why
//! it is not to be trusted) that the command line prints or writes and Python returns.

mod fluxmap;
mod mechanics;
mod report;
mod saturation;
mod shaft;
mod standstill;

pub use fluxmap::{FluxMapRequest, fluxmap};
pub use mechanics::{MechanicsRequest, mechanics};
pub use report::{Report, exponents};
pub use saturation::{SaturationRequest, saturation};
pub use standstill::{StandstillRequest, standstill};
