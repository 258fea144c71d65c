//! The committed header is the one cbindgen generates from the sources.

#[test]
fn the_header_is_current() {
    let generated = include_str!(concat!(env!("OUT_DIR"), "/greybox_observer.h"));
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/include/greybox_observer.h");
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    if committed != generated && std::env::var_os("GREYBOX_WRITE_HEADER").is_some() {
        std::fs::write(path, generated).expect("write the header");
        return;
    }
    assert!(
        committed == generated,
        "{path} is not the header cbindgen generates from the sources: \
         GREYBOX_WRITE_HEADER=1 cargo test -p greybox-observer-capi writes it"
    );
}
