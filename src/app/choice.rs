//! Values chosen by name from a fixed list: a flag's value on the command line, a keyword's
//! string in Python, parsed by the same table ([`Choice`]) so that both accept the same
//! names; the command line's `clap::ValueEnum` derivations are checked against it (tests).

use super::simulate::Motor;
use super::track::Estimator;
use super::values::{InverterChoice, Method, ModelChoice, Voltage};
use crate::estimate::{ScalingKind, SolverKind};
use crate::online::Adaptation;
use crate::pmsm::{
    AngleUnit, CarrierEdge, Frame, HoldChoice, Modulator, MotorKind, PwmUpdate, Scale, SpeedUnit, TimeUnit,
    VoltageHold,
};

/// A value chosen by its name from a fixed list.
pub trait Choice: Sized + Copy + 'static {
    /// The names and their values, each value's own name first, aliases after (the names
    /// `greybox --help` lists, `rad/s` and its alias `rad-s` for [`SpeedUnit::RadPerSec`]).
    const NAMES: &'static [(&'static str, Self)];
    /// The values' own names (aliases not repeated), as a message lists them.
    const LISTED: &'static [&'static str];

    /// The value named `s` (ASCII case ignored, as the command line's parser does).
    ///
    /// # Errors
    /// A message quoting `s` and listing the names, e.g. ``"`rpn`: expected rad/s or rpm"``.
    fn parse_choice(s: &str) -> Result<Self, String> {
        Self::NAMES.iter().find(|(name, _)| name.eq_ignore_ascii_case(s)).map(|(_, v)| *v).ok_or_else(|| {
            let list = match Self::LISTED {
                [one] => one.to_string(),
                [first @ .., last] => format!("{} or {last}", first.join(", ")),
                [] => String::new(),
            };
            format!("`{s}`: expected {list}")
        })
    }
}

/// Implements [`Choice`] with the names listed (aliases as `alias => Value` after `;`).
macro_rules! choice {
    ($t:ty: $($name:literal => $v:expr),+ $(; $($alias:literal => $av:expr),+)?) => {
        impl Choice for $t {
            const NAMES: &'static [(&'static str, Self)] = &[$(($name, $v)),+ $(, $(($alias, $av)),+)?];
            const LISTED: &'static [&'static str] = &[$($name),+];
        }
    };
}

choice!(SpeedUnit: "rad/s" => SpeedUnit::RadPerSec, "rpm" => SpeedUnit::Rpm; "rad-s" => SpeedUnit::RadPerSec);
choice!(AngleUnit: "rad" => AngleUnit::Rad, "deg" => AngleUnit::Deg);
choice!(Frame: "mechanical" => Frame::Mechanical, "electrical" => Frame::Electrical);
choice!(Scale: "peak" => Scale::Peak, "rms" => Scale::Rms);
choice!(TimeUnit: "s" => TimeUnit::S, "ms" => TimeUnit::Ms, "us" => TimeUnit::Us);
choice!(HoldChoice: "auto" => HoldChoice::Auto, "dq" => HoldChoice::Dq, "stator" => HoldChoice::Stator);
choice!(SolverKind: "auto" => SolverKind::Auto, "lm" => SolverKind::Lm, "gn" => SolverKind::Gn, "trust-region" => SolverKind::TrustRegion);
choice!(ScalingKind: "nominal" => ScalingKind::Nominal, "log" => ScalingKind::Log,
    "column-norm" => ScalingKind::ColumnNorm, "identity" => ScalingKind::Identity);
choice!(Modulator: "min-max" => Modulator::MinMax, "sine" => Modulator::Sine);
choice!(PwmUpdate: "double" => PwmUpdate::Double, "single" => PwmUpdate::Single);
choice!(CarrierEdge: "rising" => CarrierEdge::Rising, "falling" => CarrierEdge::Falling);
choice!(MotorKind: "spm" => MotorKind::Spm, "ipm" => MotorKind::Ipm);
choice!(Method: "auto" => Method::Auto, "pem" => Method::Pem, "ls" => Method::Ls, "iv" => Method::Iv);
choice!(Voltage: "actual" => Voltage::Actual, "reference" => Voltage::Reference);
choice!(ModelChoice: "spm" => ModelChoice::Spm, "ipm" => ModelChoice::Ipm,
    "spm-steady" => ModelChoice::SpmSteady, "ipm-steady" => ModelChoice::IpmSteady);
choice!(InverterChoice: "none" => InverterChoice::None, "pwm" => InverterChoice::Pwm);
choice!(Estimator: "mras" => Estimator::Mras, "ekf" => Estimator::Ekf);
choice!(Adaptation: "normalised" => Adaptation::Normalised, "lyapunov" => Adaptation::Lyapunov,
    "relay" => Adaptation::Relay);
choice!(VoltageHold: "stator" => VoltageHold::Stator, "dq" => VoltageHold::Dq);
choice!(Motor: "spm" => Motor::Spm, "ipm" => Motor::Ipm, "ipm-sat" => Motor::IpmSat);

#[cfg(test)]
mod tests {
    use super::*;

    /// The table's names are clap's, aliases included, for every value.
    #[cfg(feature = "cli")]
    fn same_as_clap<T: Choice + clap::ValueEnum + PartialEq + std::fmt::Debug>() {
        let mut clap_names: Vec<(String, T)> = Vec::new();
        for v in T::value_variants() {
            let p = v.to_possible_value().expect("every value is listed");
            clap_names.push((p.get_name().to_string(), *v));
            for alias in p.get_name_and_aliases().skip(1) {
                clap_names.push((alias.to_string(), *v));
            }
        }
        let ours: Vec<(String, T)> = T::NAMES.iter().map(|(n, v)| (n.to_string(), *v)).collect();
        let (mut a, mut b) = (clap_names, ours);
        a.sort_by(|x, y| x.0.cmp(&y.0));
        b.sort_by(|x, y| x.0.cmp(&y.0));
        assert_eq!(a, b);
        let listed: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value())
            .map(|p| p.get_name().into())
            .collect();
        assert_eq!(listed, T::LISTED);
    }

    #[cfg(feature = "cli")]
    #[test]
    fn the_names_are_the_command_lines() {
        same_as_clap::<SpeedUnit>();
        same_as_clap::<AngleUnit>();
        same_as_clap::<Frame>();
        same_as_clap::<Scale>();
        same_as_clap::<TimeUnit>();
        same_as_clap::<HoldChoice>();
        same_as_clap::<SolverKind>();
        same_as_clap::<ScalingKind>();
        same_as_clap::<Modulator>();
        same_as_clap::<PwmUpdate>();
        same_as_clap::<CarrierEdge>();
        same_as_clap::<MotorKind>();
        same_as_clap::<Method>();
        same_as_clap::<Voltage>();
        same_as_clap::<ModelChoice>();
        same_as_clap::<InverterChoice>();
        // `greybox track`'s values are the command line's own enums, converted.
        use crate::cli::track::{AdaptationArg, EstimatorArg, TrackHold};
        fn listed<T: clap::ValueEnum>() -> Vec<String> {
            T::value_variants()
                .iter()
                .filter_map(|v| v.to_possible_value())
                .map(|p| p.get_name().into())
                .collect()
        }
        assert_eq!(listed::<EstimatorArg>(), Estimator::LISTED);
        assert_eq!(listed::<AdaptationArg>(), Adaptation::LISTED);
        assert_eq!(listed::<TrackHold>(), VoltageHold::LISTED);
        assert_eq!(listed::<crate::cli::simulate::MotorArg>(), Motor::LISTED);
        let mut hold = listed::<crate::cli::validate::ValidateHold>();
        hold.sort();
        assert_eq!(hold, ["dq", "stator"]);
    }

    #[test]
    fn a_wrong_name_lists_the_right_ones() {
        assert_eq!(SpeedUnit::parse_choice("RPM"), Ok(SpeedUnit::Rpm));
        assert_eq!(SpeedUnit::parse_choice("rad-s"), Ok(SpeedUnit::RadPerSec));
        assert_eq!(
            Voltage::parse_choice("referense").unwrap_err(),
            "`referense`: expected actual or reference"
        );
        assert_eq!(TimeUnit::parse_choice("h").unwrap_err(), "`h`: expected s, ms or us");
    }
}
