//! `salvq info` of a small fixed stream, snapshot-tested: any change to the format or to the
//! generator shows up in review as a changed snapshot.

mod common;

use salvq::Limits;
use salvq_encoder::info::inspect;

#[test]
fn info_text_of_a_small_stream() {
    let s = common::small_stream();
    insta::assert_snapshot!(inspect(&s, &Limits::default()).unwrap().to_text());
}

#[test]
fn info_json_of_a_small_stream() {
    let s = common::small_stream();
    let info = inspect(&s, &Limits::default()).unwrap();
    insta::assert_snapshot!(serde_json::to_string_pretty(&info).unwrap());
}
