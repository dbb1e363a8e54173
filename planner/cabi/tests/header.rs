//! `include/dkrrt_plan.h` describes the Rust types: a C compiler's sizes and offsets of the
//! header's structs equal Rust's, and its `DK_NJ` is the arm's joint count.

use std::mem::{offset_of, size_of};
use std::process::Command;

use dkrrt_plan_cabi::{DkCounts, DkInfo, DK_NJ};

#[test]
fn the_header_matches_the_rust_layouts() {
    let dir = std::env::temp_dir().join(format!("dkrrt-cabi-header-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let src = dir.join("layout.c");
    std::fs::write(
        &src,
        r#"#include <stddef.h>
#include <stdio.h>
#include "dkrrt_plan.h"
int main(void) {
    printf("%zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %d\n", sizeof(DkInfo),
           offsetof(DkInfo, goal), offsetof(DkInfo, q_min), offsetof(DkInfo, q_max),
           offsetof(DkInfo, time_limit_s), offsetof(DkInfo, seed), offsetof(DkInfo, still),
           offsetof(DkInfo, start_clear_m), offsetof(DkInfo, goal_clear_m),
           offsetof(DkInfo, delta_m), sizeof(DkCounts), offsetof(DkCounts, check_s), DK_NJ);
    return 0;
}
"#,
    )
    .unwrap();
    let exe = dir.join("layout");
    let include = concat!(env!("CARGO_MANIFEST_DIR"), "/include");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Werror", "-I", include, "-o"])
        .arg(&exe)
        .arg(&src)
        .output()
        .unwrap_or_else(|e| panic!("the C compiler `{cc}` (set CC to another): {e}"));
    assert!(out.status.success(), "the header does not compile: {}", String::from_utf8_lossy(&out.stderr));
    let run = Command::new(&exe).output().unwrap();
    let got: Vec<usize> =
        String::from_utf8_lossy(&run.stdout).split_whitespace().map(|x| x.parse().unwrap()).collect();
    let want = vec![
        size_of::<DkInfo>(),
        offset_of!(DkInfo, goal),
        offset_of!(DkInfo, q_min),
        offset_of!(DkInfo, q_max),
        offset_of!(DkInfo, time_limit_s),
        offset_of!(DkInfo, seed),
        offset_of!(DkInfo, still),
        offset_of!(DkInfo, start_clear_m),
        offset_of!(DkInfo, goal_clear_m),
        offset_of!(DkInfo, delta_m),
        size_of::<DkCounts>(),
        offset_of!(DkCounts, check_s),
        DK_NJ,
    ];
    assert_eq!(got, want, "C (header) against Rust: sizes and offsets");
    let _ = std::fs::remove_dir_all(&dir);
}
