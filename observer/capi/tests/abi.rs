//! The C ABI called as C calls it: codes for null pointers, bad settings and bad samples,
//! their names, and the same estimates as the Rust observers.

use greybox_observer::{Kalman, Mras, Noise, Sample, Settings};
use greybox_observer_capi::*;
use std::ffi::CStr;
use std::mem::MaybeUninit;
use std::ptr::{null, null_mut};

fn name(code: i32) -> String {
    // SAFETY: gb_error_name returns a static NUL-terminated string.
    unsafe { CStr::from_ptr(gb_error_name(code)) }.to_string_lossy().into_owned()
}

fn settings() -> GbSettingsF64 {
    let mut s = MaybeUninit::<GbSettingsF64>::uninit();
    // SAFETY: a valid pointer to writable storage.
    assert_eq!(unsafe { gb_settings_f64_default(4, 4.5e-3, 1e-4, s.as_mut_ptr()) }, GB_OK);
    // SAFETY: written above.
    let mut s = unsafe { s.assume_init() };
    (s.k_e0, s.r_s0) = (0.45, 0.7);
    s
}

/// `x` in `float` (each channel rounded).
fn narrow(x: &Sample<f64>) -> Sample<f32> {
    Sample { i_d: x.i_d as f32, i_q: x.i_q as f32, u_d: x.u_d as f32, u_q: x.u_q as f32, w_m: x.w_m as f32 }
}

#[test]
fn codes_for_nulls_settings_and_samples() {
    let mut s = settings();
    let mut mras = MaybeUninit::<GbMrasF64>::uninit();
    // SAFETY: null pointers are refused; the others are valid.
    unsafe {
        assert_eq!(gb_mras_f64_init(null_mut(), &s), GB_ERR_NULL);
        assert_eq!(gb_mras_f64_init(mras.as_mut_ptr(), null()), GB_ERR_NULL);
        assert_eq!(gb_settings_f64_default(4, 1.0, 1.0, null_mut()), GB_ERR_NULL);
        s.l_s = -1.0;
        let code = gb_mras_f64_init(mras.as_mut_ptr(), &s);
        assert_eq!(code, GB_ERR_SETTING - 1);
        assert_eq!(name(code), "setting l_s out of range (positive)");
        s.l_s = 4.5e-3;
        assert_eq!(gb_mras_f64_init(mras.as_mut_ptr(), &s), GB_OK);
        let mut e = MaybeUninit::<GbEstimatesF64>::uninit();
        let bad = Sample { i_d: 0.0, i_q: 1.0, u_d: 0.0, u_q: f64::NAN, w_m: 10.0 };
        let code = gb_mras_f64_update(mras.as_mut_ptr(), &bad, e.as_mut_ptr());
        assert_eq!(code, GB_ERR_NON_FINITE - 3);
        assert_eq!(name(code), "non-finite u_q");
        assert_eq!(gb_mras_f64_update(mras.as_mut_ptr(), null(), e.as_mut_ptr()), GB_ERR_NULL);
        let mut noise = MaybeUninit::<GbNoiseF64>::uninit();
        assert_eq!(gb_noise_f64_for_machine(0.0, 0.7, 0.45, noise.as_mut_ptr()), GB_OK);
        let mut kf = MaybeUninit::<GbKalmanF64>::uninit();
        let code = gb_kalman_f64_init(kf.as_mut_ptr(), &s, noise.as_ptr());
        assert_eq!(code, GB_ERR_SETTING - 11);
        assert_eq!(name(code), "setting sigma_i out of range (positive)");
    }
    assert_eq!(name(GB_OK), "ok");
    assert_eq!(name(12345), "unknown code");
}

/// The ABI's observers are the Rust ones: the same estimates to the bit, in both precisions.
#[test]
fn the_abi_gives_the_rust_observers_estimates() {
    let s = settings();
    let noise = Noise::for_machine(0.01, s.r_s0, s.k_e0);
    let (mut m, mut k) = (Mras::spm(s).unwrap(), Kalman::spm(s, noise).unwrap());
    let mut mras = MaybeUninit::<GbMrasF64>::uninit();
    let mut kf = MaybeUninit::<GbKalmanF64>::uninit();
    let s32: Settings<f32> = {
        let mut x = MaybeUninit::uninit();
        // SAFETY: valid storage.
        assert_eq!(unsafe { gb_settings_f32_default(4, 4.5e-3, 1e-4, x.as_mut_ptr()) }, GB_OK);
        // SAFETY: written above.
        let mut x = unsafe { x.assume_init() };
        (x.k_e0, x.r_s0) = (0.45, 0.7);
        x
    };
    let mut m32 = Mras::spm(s32).unwrap();
    let mut mras32 = MaybeUninit::<GbMrasF32>::uninit();
    // SAFETY: valid pointers throughout.
    unsafe {
        assert_eq!(gb_mras_f64_init(mras.as_mut_ptr(), &s), GB_OK);
        assert_eq!(gb_kalman_f64_init(kf.as_mut_ptr(), &s, &noise), GB_OK);
        assert_eq!(gb_mras_f32_init(mras32.as_mut_ptr(), &s32), GB_OK);
        for j in 0..5000 {
            let x = signal(j, 1.0, -2.0);
            let mut e = MaybeUninit::<GbEstimatesF64>::uninit();
            assert_eq!(gb_mras_f64_update(mras.as_mut_ptr(), &x, e.as_mut_ptr()), GB_OK);
            assert_eq!(e.assume_init(), m.update(&x).unwrap());
            assert_eq!(gb_kalman_f64_update(kf.as_mut_ptr(), &x, e.as_mut_ptr()), GB_OK);
            assert_eq!(e.assume_init(), k.update(&x).unwrap());
            let x32 = narrow(&x);
            let mut e32 = MaybeUninit::<GbEstimatesF32>::uninit();
            assert_eq!(gb_mras_f32_update(mras32.as_mut_ptr(), &x32, e32.as_mut_ptr()), GB_OK);
            assert_eq!(e32.assume_init(), m32.update(&x32).unwrap());
        }
    }
}

/// Sample j of the tests' signal at 10 kHz: sinusoids around the d current `i_d0` \[A\] and
/// the d voltage `u_d0` \[V\], `i_q` about 3 A, `u_q` about 40 V, `w_m` about 100 rad/s.
fn signal(j: usize, i_d0: f64, u_d0: f64) -> Sample<f64> {
    let t = j as f64 * 1e-4;
    Sample {
        i_d: i_d0 + (30.0 * t).sin(),
        i_q: 3.0 + 0.5 * (70.0 * t).cos(),
        u_d: u_d0 + (50.0 * t).sin(),
        u_q: 40.0 + (20.0 * t).cos(),
        w_m: 100.0 + 10.0 * (5.0 * t).sin(),
    }
}

/// A salient machine through `_init_salient`: the Rust observers of `Machine::Ipm` to the
/// bit, in both precisions; a bad `l_q` named; a negative running `R_s` is the step's code.
#[test]
fn the_salient_abi_gives_the_rust_observers_estimates() {
    use greybox_observer::Machine;
    let s = settings();
    let l_q = 9e-3;
    let noise = Noise::for_machine(0.01, s.r_s0, s.k_e0);
    let machine = Machine::of(&s, Some(l_q)).unwrap();
    let (mut m, mut k) = (Mras::new(s, machine).unwrap(), Kalman::new(s, machine, noise).unwrap());
    let mut mras = MaybeUninit::<GbMrasF64>::uninit();
    let mut kf = MaybeUninit::<GbKalmanF64>::uninit();
    let mut s32 = Settings::<f32>::new(4, 4.5e-3, 1e-4);
    (s32.k_e0, s32.r_s0) = (0.45, 0.7);
    let noise32 = Noise::for_machine(0.01f32, s32.r_s0, s32.k_e0);
    let machine32 = Machine::of(&s32, Some(l_q as f32)).unwrap();
    let mut k32 = Kalman::new(s32, machine32, noise32).unwrap();
    let mut kf32 = MaybeUninit::<GbKalmanF32>::uninit();
    // SAFETY: valid pointers throughout.
    unsafe {
        let code = gb_mras_f64_init_salient(mras.as_mut_ptr(), &s, -1.0);
        assert_eq!(code, GB_ERR_SETTING - 17);
        assert_eq!(name(code), "setting l_q out of range (positive)");
        assert_eq!(gb_kalman_f64_init_salient(null_mut(), &s, l_q, &noise), GB_ERR_NULL);
        assert_eq!(gb_mras_f64_init_salient(mras.as_mut_ptr(), &s, l_q), GB_OK);
        assert_eq!(gb_kalman_f64_init_salient(kf.as_mut_ptr(), &s, l_q, &noise), GB_OK);
        assert_eq!(gb_kalman_f32_init_salient(kf32.as_mut_ptr(), &s32, l_q as f32, &noise32), GB_OK);
        for j in 0..3000 {
            let x = signal(j, -2.0, -12.0);
            let mut e = MaybeUninit::<GbEstimatesF64>::uninit();
            assert_eq!(gb_mras_f64_update(mras.as_mut_ptr(), &x, e.as_mut_ptr()), GB_OK);
            assert_eq!(e.assume_init(), m.update(&x).unwrap());
            assert_eq!(gb_kalman_f64_update(kf.as_mut_ptr(), &x, e.as_mut_ptr()), GB_OK);
            assert_eq!(e.assume_init(), k.update(&x).unwrap());
            let x32 = narrow(&x);
            let mut e32 = MaybeUninit::<GbEstimatesF32>::uninit();
            assert_eq!(gb_kalman_f32_update(kf32.as_mut_ptr(), &x32, e32.as_mut_ptr()), GB_OK);
            assert_eq!(e32.assume_init(), k32.update(&x32).unwrap());
        }
    }
    assert_eq!(name(GB_ERR_STEP), "the salient step failed");
}
