//! A flux map's self-consistency (issue 43, item 1): the saturation model refitted on four
//! regions of the map agrees where the model describes the map, and where it does not the
//! coefficients' intervals widen by the regions' spread.

use crate::common::{Rng, data, require_shared};
use crate::saturation::{MAP_MOTOR, synthetic_map};
use greybox::data::Channel;
use greybox::pmsm::{FluxMapOptions, fit_flux_map, read_flux_map};

/// Noisy maps of the model's own family (σ = 2 mV s, the exponents given): the regions
/// agree on every one of 40 seeds (family level 1e-3: a false alarm in 40 maps would have
/// probability about 0.04), and no interval is widened.
#[test]
fn regions_of_a_map_of_the_model_family_agree() {
    let mut rng = Rng(7);
    let options = FluxMapOptions { exponents: Some(MAP_MOTOR.exponents), skip_check: false };
    for seed in 0..40 {
        let map = synthetic_map(&MAP_MOTOR, 2e-3, &mut rng);
        let fit = fit_flux_map(&map, &options).unwrap();
        let r = fit.regions.as_ref().expect("a 21 × 27 map is split");
        assert_eq!(r.regions.len(), 4);
        assert!(r.tests.len() >= 5, "seed {seed}: {:?}", r.tests);
        assert!(r.disagreement.is_none() && r.widened.is_empty(), "seed {seed}: {:?}", r.disagreement);
    }
}

/// A map the family cannot describe: the model's map with a knee of 20 mV s in ψ_d at low
/// current (as a measured map's). The regions disagree on ψ_f (0.464, 0.450, 0.459,
/// 0.450 V s); its interval from the white covariance (the residuals are model error)
/// holds none of them, its interval with the regions' spread (t quantile on 3 degrees of
/// freedom) holds all four. (The no-load figure a user reads is the map check's.)
#[test]
fn a_map_beyond_the_model_family_widens_its_intervals() {
    let map = synthetic_map(&MAP_MOTOR, 0.0, &mut Rng(1));
    let (i_d, i_q) = (map.channel("i_d").unwrap(), map.channel("i_q").unwrap());
    let knee = |d: f64, q: f64| 0.02 * (-(d * d + q * q) / 50.0).exp();
    let psi_d: Vec<f64> = map
        .channel("psi_d")
        .unwrap()
        .iter()
        .zip(i_d.iter().zip(i_q))
        .map(|(p, (d, q))| p + knee(*d, *q))
        .collect();
    let map = map.with_channel(Channel::new("psi_d", "V s", psi_d)).unwrap();
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    let r = fit.regions.as_ref().unwrap();
    eprintln!("{r}");
    assert!(r.disagreement.as_ref().is_some_and(|w| w.contains("psi_f")), "{:?}", r.disagreement);
    holds_the_regions(&fit, "psi_f");
}

/// The measured Baldor map (shared): its regions disagree on ψ_f (0.449 … 0.509 V s); the
/// white interval (0.4952 … 0.5011 V s) holds none of them, the interval with their spread
/// holds all four, and the map's no-load flux 0.4441 V s too (which the white one misses
/// by 12 %).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the development logs: ../shared/data or $GREYBOX_SHARED_DATA")]
fn the_measured_map_widens_its_intervals() {
    require_shared!();
    let map = read_flux_map(data("real/baldor_400rpm_map.npz")).unwrap();
    let fit = fit_flux_map(&map, &FluxMapOptions::default()).unwrap();
    let psi_f = holds_the_regions(&fit, "psi_f");
    let no_load = fit.check.as_ref().and_then(|c| c.no_load_map).unwrap();
    assert!(psi_f[0] <= no_load && no_load <= psi_f[1], "{psi_f:?} against {no_load}");
}

/// Asserts that the regions disagree on `name`, whose white interval holds none of the
/// regions' estimates and whose widened interval holds every one; returns the latter.
fn holds_the_regions(fit: &greybox::pmsm::FluxMapFit, name: &str) -> [f64; 2] {
    let r = fit.regions.as_ref().unwrap();
    let test = r.tests.iter().find(|h| h.name == name).unwrap();
    let white = fit.fit.parameter(name).unwrap().ci95;
    let widened = r.widened.iter().find(|w| w.name == name).unwrap();
    assert!(widened.tau > 10.0 * widened.std_error, "{widened:?}");
    for e in &test.estimates {
        assert!(!(white[0] <= *e && *e <= white[1]), "{e} inside the white {white:?}");
        assert!(widened.interval[0] <= *e && *e <= widened.interval[1], "{e} outside {widened:?}");
    }
    widened.interval
}
