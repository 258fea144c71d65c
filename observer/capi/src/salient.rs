//! The salient machine's observers (`L_d ≠ L_q`, `L_q` known): the `_init_salient`
//! functions, whose observers the same `_update` functions run.

use crate::{
    GB_ERR_NULL, GbKalmanF32, GbKalmanF64, GbMrasF32, GbMrasF64, GbNoiseF32, GbNoiseF64, GbSettingsF32,
    GbSettingsF64, init, kalman, mras,
};

/// [`gb_mras_f64_init`](crate::gb_mras_f64_init) of a salient machine: `settings.l_s` is
/// `L_d`, `l_q` is `L_q` \[H\]
/// (the augmented exponential's step; equal to `l_s`, the surface-magnet step); also
/// [`GB_ERR_SETTING`](crate::GB_ERR_SETTING) minus 17 for an `l_q` that is not positive and finite.
///
/// # Safety
/// As [`gb_mras_f64_init`](crate::gb_mras_f64_init).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gb_mras_f64_init_salient(
    obs: *mut GbMrasF64,
    settings: *const GbSettingsF64,
    l_q: f64,
) -> i32 {
    if obs.is_null() || settings.is_null() {
        return GB_ERR_NULL;
    }
    // SAFETY: non-null and valid (the caller's contract).
    unsafe { init(obs, mras(&*settings, Some(l_q))) }
}

/// [`gb_mras_f64_init_salient`] in `float`.
///
/// # Safety
/// As [`gb_mras_f64_init`](crate::gb_mras_f64_init).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gb_mras_f32_init_salient(
    obs: *mut GbMrasF32,
    settings: *const GbSettingsF32,
    l_q: f32,
) -> i32 {
    if obs.is_null() || settings.is_null() {
        return GB_ERR_NULL;
    }
    // SAFETY: non-null and valid (the caller's contract).
    unsafe { init(obs, mras(&*settings, Some(l_q))) }
}

/// [`gb_kalman_f64_init`](crate::gb_kalman_f64_init) of a salient machine: `settings.l_s`
/// is `L_d`, `l_q` is `L_q`
/// \[H\]; the codes of [`gb_mras_f64_init_salient`].
///
/// # Safety
/// As [`gb_kalman_f64_init`](crate::gb_kalman_f64_init).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gb_kalman_f64_init_salient(
    kf: *mut GbKalmanF64,
    settings: *const GbSettingsF64,
    l_q: f64,
    noise: *const GbNoiseF64,
) -> i32 {
    if kf.is_null() || settings.is_null() || noise.is_null() {
        return GB_ERR_NULL;
    }
    // SAFETY: non-null and valid (the caller's contract).
    unsafe { init(kf, kalman(&*settings, Some(l_q), &*noise)) }
}

/// [`gb_kalman_f64_init_salient`] in `float`.
///
/// # Safety
/// As [`gb_kalman_f64_init`](crate::gb_kalman_f64_init).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gb_kalman_f32_init_salient(
    kf: *mut GbKalmanF32,
    settings: *const GbSettingsF32,
    l_q: f32,
    noise: *const GbNoiseF32,
) -> i32 {
    if kf.is_null() || settings.is_null() || noise.is_null() {
        return GB_ERR_NULL;
    }
    // SAFETY: non-null and valid (the caller's contract).
    unsafe { init(kf, kalman(&*settings, Some(l_q), &*noise)) }
}
