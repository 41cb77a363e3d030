//! The `backlash` binary as a user runs it: its exit status, and what it writes where.

mod common;

use common::{backlash, text};

#[test]
fn bad_input_gives_one_error_line_and_status_2() {
    for args in [
        &[][..],
        &["desing"],
        &["design"],
        &["design", "--accuracy", "-1"],
        &["design", "--accuracy", "nan"],
        &["design", "--accuracy", "0.02", "--frobnicate"],
        &["design", "--model", "web"],
        &[
            "design",
            "--model",
            "belt",
            "--accuracy",
            "0.02",
            "--tension-accuracy",
            "1",
        ],
        // Given gains that make the loop unstable: no finite bound, so no answer.
        &["design", "--accuracy", "0.02", "--kp", "-50", "--ki", "1"],
    ] {
        let out = backlash(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert_eq!(text(&out.stdout), "", "{args:?}");
        let stderr = text(&out.stderr);
        assert!(
            stderr.starts_with("error: ") && stderr.ends_with('\n') && stderr.lines().count() == 1,
            "{args:?}: {stderr:?}"
        );
    }
}

#[test]
fn help_goes_to_stdout() {
    for (args, first) in [
        (&["--help"][..], "usage: backlash <command> [args]"),
        (&["help"], "usage: backlash <command> [args]"),
        (
            &["design", "--help"],
            "usage: backlash design --accuracy EPS [--model shaft|belt|two-stage] [options] [--json]",
        ),
    ] {
        let out = backlash(args);
        assert_eq!(out.status.code(), Some(0), "{args:?}");
        assert_eq!(text(&out.stdout).lines().next(), Some(first), "{args:?}");
        assert_eq!(text(&out.stderr), "");
    }
}

#[test]
fn the_answer_is_the_librarys_with_a_final_newline() {
    // Given gains: no gain search, so the run is short.
    let args = ["--accuracy", "0.02", "--kp", "40", "--ki", "150", "--json"];
    let out = backlash(&[&["design"][..], &args].concat());
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let owned: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    let expected = backlash_design::cli::design("backlash design", &owned).unwrap() + "\n";
    assert_eq!(text(&out.stdout), expected);
    let answer: serde_json::Value = serde_json::from_str(&expected).unwrap();
    assert_eq!(
        (answer["Kp"].as_f64(), answer["gain_rule"].as_str()),
        (Some(40.0), Some("given"))
    );
}
