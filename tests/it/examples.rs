//! The examples that prove the open architecture run as tests, each asserting its own
//! figures: a user-defined SPM that reproduces `PmsmSpm` (≤ 30 lines of model code, 1e-10),
//! a non-motor thermal model recovered noise-free to 1e-6 and with noise within 3 standard
//! errors, and a static regression fitted from its first sample without padding.

#[path = "../../examples/static_regression.rs"]
mod static_regression;
#[path = "../../examples/thermal.rs"]
mod thermal;
#[path = "../../examples/user_spm.rs"]
mod user_spm;

/// The user-defined SPM is at most 30 lines of model code (comments and blank lines not
/// counted), as formatted by rustfmt.
#[test]
fn user_spm_model_code_is_at_most_30_lines() {
    let text = include_str!("../../examples/user_spm.rs");
    let start = text.find("// --- model code").expect("start marker");
    let end = text.find("// --- end of model code ---").expect("end marker");
    let body = &text[start..end];
    let code =
        body.lines().skip(1).filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with("//")).count();
    assert!(code <= 30, "{code} lines of model code");
    assert!(!body.contains("rustfmt::skip"));
}
