//! The return codes of the C ABI and their names.

use core::ffi::{CStr, c_char};
use greybox_observer::{Fault, Field};

/// Success.
pub const GB_OK: i32 = 0;
/// A setting out of range is `GB_ERR_SETTING - field` (fields in `greybox_observer::Field`'s order:
/// 0 `n_p`, 1 `l_s`, 2 `h`, 3 `tau_ke`, 4 `tau_rs`, 5 `f`, 6 `gamma_ke`, 7 `i_d_threshold`,
/// 8 `r_s0`, 9 `gamma_rs`, 10 `k_e0`, 11 `sigma_i`, 12 `p0_r_s`, 13 `p0_k_e`, 14 `q_i`,
/// 15 `q_r_s`, 16 `q_k_e`, 17 `l_q`).
pub const GB_ERR_SETTING: i32 = -100;
/// A null pointer was passed.
pub const GB_ERR_NULL: i32 = -1;
/// A sample's value is NaN or infinite: `GB_ERR_NON_FINITE - channel` (0 `i_d`, 1 `i_q`,
/// 2 `u_d`, 3 `u_q`, 4 `w_m`).
pub const GB_ERR_NON_FINITE: i32 = -10;
/// A singular matrix (the MRAS's adaptation, the filter's innovation covariance).
pub const GB_ERR_SINGULAR: i32 = -2;
/// The estimates or the state would stop being finite.
pub const GB_ERR_NOT_FINITE: i32 = -3;
/// The salient machine's step failed (a running `R_s` below 0 or a `K_e` not finite, a
/// period too long for its series: `greybox_observer::StepError`).
pub const GB_ERR_STEP: i32 = -4;

pub(crate) fn setting(field: Field) -> i32 {
    GB_ERR_SETTING - field as i32
}

pub(crate) fn fault<T, E>(f: Fault<T, E>) -> i32 {
    match f {
        Fault::NonFinite { channel, .. } => GB_ERR_NON_FINITE - channel as i32,
        Fault::Singular { .. } => GB_ERR_SINGULAR,
        Fault::Step { .. } => GB_ERR_STEP,
        Fault::NotFinite { .. } | Fault::Stale { .. } => GB_ERR_NOT_FINITE,
    }
}

/// The name of a return code (`"ok"`, `"setting l_s out of range"`, `"non-finite w_m"`, …),
/// a static NUL-terminated string.
#[unsafe(no_mangle)]
pub extern "C" fn gb_error_name(code: i32) -> *const c_char {
    const SETTINGS: [&CStr; 18] = [
        c"setting n_p out of range (at least 1)",
        c"setting l_s out of range (positive)",
        c"setting h out of range (positive)",
        c"setting tau_ke out of range (positive; normalised: at least 100 h)",
        c"setting tau_rs out of range (positive; normalised: at least 100 h)",
        c"setting f out of range (at least 0)",
        c"setting gamma_ke out of range (at least 0)",
        c"setting i_d_threshold out of range (at least 0)",
        c"setting r_s0 out of range (at least 0)",
        c"setting gamma_rs out of range (at most 0)",
        c"setting k_e0 out of range (finite)",
        c"setting sigma_i out of range (positive)",
        c"setting p0_r_s out of range (positive)",
        c"setting p0_k_e out of range (positive)",
        c"setting q_i out of range (at least 0)",
        c"setting q_r_s out of range (at least 0)",
        c"setting q_k_e out of range (at least 0)",
        c"setting l_q out of range (positive)",
    ];
    const CHANNELS: [&CStr; 5] =
        [c"non-finite i_d", c"non-finite i_q", c"non-finite u_d", c"non-finite u_q", c"non-finite w_m"];
    let name = match code {
        GB_OK => c"ok",
        GB_ERR_NULL => c"null pointer",
        GB_ERR_SINGULAR => c"singular matrix",
        GB_ERR_NOT_FINITE => c"estimates not finite",
        GB_ERR_STEP => c"the salient step failed",
        c if (GB_ERR_NON_FINITE - 4..=GB_ERR_NON_FINITE).contains(&c) => {
            CHANNELS[(GB_ERR_NON_FINITE - c) as usize]
        }
        c if (GB_ERR_SETTING - 17..=GB_ERR_SETTING).contains(&c) => SETTINGS[(GB_ERR_SETTING - c) as usize],
        _ => c"unknown code",
    };
    name.as_ptr()
}
