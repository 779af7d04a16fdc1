//! Tests of the log reader ([`super`]).

use super::*;

const HEAD: &str = "t_s,theta_fb_rad,i_q_a\n";

/// A good log body: `rows` rows at 20 kHz, 1 rad/s.
fn body(rows: usize) -> String {
    (0..rows).map(|i| format!("{},{},0.1\n", i as f64 * 5e-5, i as f64 * 5e-5)).collect()
}

fn parse(text: &str) -> Result<RunLog, LogError> {
    parse_log(text.as_bytes(), "run.csv", &LogOptions::new(50))
}

#[test]
fn a_good_log_parses_in_any_column_order_and_names_unknown_columns() {
    let mut text = String::from("i_q_a,volts,theta_fb_rad,t_s,omega_fb_rad_s\n");
    for i in 0..2000 {
        text += &format!("0.2,1,{},{},0\n", i as f64 * 5e-4, i as f64 * 5e-5);
    }
    let log = parse(&text).unwrap();
    assert_eq!(log.len(), 2000);
    assert_eq!(log.ignored_columns, vec!["volts".to_string()]);
    assert_eq!((log.i_q_a[5], log.iq_source), (0.2, IqSource::Column));
    assert!(log.iq_cmd_a.is_none());
}

#[test]
fn a_missing_column_names_the_file_the_header_line_and_the_column() {
    let e = parse("theta_fb_rad,i_q_a\n0,0\n").unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("line 1") && e.contains("'t_s'"), "{e}");
    let e = parse("t_s,i_q_a\n0,0\n").unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("'theta_fb_rad'"), "{e}");
    let e = parse("t_s,theta_fb_rad\n0,0\n").unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("'i_q_a'") && e.contains("i_a_a and i_b_a"), "{e}");
    let e = parse("t_s,theta_fb_rad,i_a_a\n0,0,0\n").unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("'i_b_a'"), "{e}");
    let e = parse("t_s,theta_fb_rad,i_q_a,t_s\n0,0,0,0\n").unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("twice"), "{e}");
}

#[test]
fn time_that_does_not_increase_names_the_file_line_and_column() {
    let text = format!("{HEAD}0.0,0,0\n0.1,0,0\n0.1,0,0\n");
    let e = parse(&text).unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("line 4") && e.contains("'t_s'") && e.contains("increase"), "{e}");
    let text = format!("{HEAD}0.0,0,0\n0.2,0,0\n0.1,0,0\n");
    assert!(parse(&text).unwrap_err().to_string().contains("line 4"));
}

#[test]
fn nan_or_unparseable_values_name_the_file_line_and_column() {
    for bad in ["NaN", "inf", "abc", ""] {
        let text = format!("{HEAD}0.0,0,0\n0.00005,0,{bad}\n");
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("line 3") && e.contains("'i_q_a'"), "{bad}: {e}");
    }
    let text = format!("{HEAD}{}0.5,0.5\n", body(3));
    let e = parse(&text).unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("line 5") && e.contains("2 fields"), "{e}");
    let text = format!("{HEAD}{}0.5,0.5,0.1,7\n", body(3));
    let e = parse(&text).unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("line 5") && e.contains("4 fields, the header has 3"), "{e}");
}

#[test]
fn a_log_of_a_rotor_at_standstill_says_so() {
    let mut text = String::from(HEAD);
    for i in 0..6000 {
        text += &format!("{},0.1,0.2\n", i as f64 * 5e-5);
    }
    let e = parse(&text).unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("0.00 electrical periods") && e.contains("stands still"), "{e}");
}

#[test]
fn a_log_that_is_too_short_says_how_many_electrical_periods_it_covers() {
    // 1000 rows at 1 rad/s = 0.05 rad = 0.40 electrical periods of 2π/50.
    let e = parse(&format!("{HEAD}{}", body(1000))).unwrap_err().to_string();
    assert!(e.contains("run.csv") && e.contains("0.40 electrical periods") && e.contains("at least 2"), "{e}");
    assert!(e.contains("lines 2–1001"), "{e}");
    assert!(parse(&format!("{HEAD}{}", body(6000))).is_ok());
}

#[test]
fn empty_and_unreadable_files_are_named() {
    assert!(parse("").unwrap_err().to_string().contains("run.csv: empty file"));
    assert!(parse(HEAD).unwrap_err().to_string().contains("run.csv: no data rows"));
    let e = read_log(Path::new("/no/such/dir/x.csv"), &LogOptions::new(50)).unwrap_err().to_string();
    assert!(e.contains("/no/such/dir/x.csv") && e.contains("cannot read"), "{e}");
}

#[test]
fn an_endless_input_is_refused_at_the_line_bound() {
    let e = read_log(Path::new("/dev/zero"), &LogOptions::new(50)).unwrap_err().to_string();
    assert!(e.contains("/dev/zero: line 1 is longer than 65536 bytes"), "{e}");
    // A good header, then endless zeros: refused on line 2, having buffered one line.
    let endless = HEAD.as_bytes().chain(std::io::repeat(0));
    let e = parse_log(endless, "run.csv", &LogOptions::new(50)).unwrap_err().to_string();
    assert!(e.contains("run.csv: line 2 is longer than"), "{e}");
}

#[test]
fn a_very_wide_header_is_refused_on_line_one() {
    let wide: String = (0..200_000).map(|i| format!("c{i},")).collect();
    let e = parse(&format!("{wide}\n0\n")).unwrap_err().to_string();
    assert!(e.contains("run.csv: line 1 is longer than 65536 bytes"), "{e}");
    // Within the byte bound but over the column bound.
    let many: Vec<String> = (0..MAX_COLUMNS + 1).map(|i| format!("{i}")).collect();
    let e = parse(&format!("{}\n", many.join(","))).unwrap_err().to_string();
    assert!(e.contains("line 1 (header): 1025 columns, at most 1024"), "{e}");
}

#[test]
fn a_missing_column_lists_a_bounded_number_of_names_and_duplicates_are_found_among_many() {
    let names: Vec<String> = (0..MAX_COLUMNS).map(|i| format!("x{i}")).collect();
    let e = parse(&format!("{}\n", names.join(","))).unwrap_err().to_string();
    assert!(e.contains("x19, … (1024 columns in all)") && !e.contains("x20,"), "{e}");
    let mut dup = names.clone();
    dup[MAX_COLUMNS - 1] = "x3".into();
    let e = parse(&format!("{}\n", dup.join(","))).unwrap_err().to_string();
    assert!(e.contains("'x3' appears twice"), "{e}");
}

#[test]
fn binary_bytes_from_the_file_are_never_echoed_raw() {
    let text = format!("{HEAD}0.0,0,\x1b[2J\x07\n");
    let e = parse(&text).unwrap_err().to_string();
    assert!(!e.contains('\x1b') && !e.contains('\x07') && e.contains("\\u{1b}[2J"), "{e}");
    let e = parse_log(&b"t_s,\xff\x1b]0;x\x07\n"[..], "run.csv", &LogOptions::new(50)).unwrap_err().to_string();
    assert!(!e.contains('\x1b') && !e.contains('\x07') && e.contains("line 1"), "{e}");
    let long = "9".repeat(1000);
    let e = parse(&format!("{HEAD}0.0,0,{long}x\n")).unwrap_err().to_string();
    assert!(e.len() < 300, "{e}");
}

#[test]
fn a_header_quoted_by_a_spreadsheet_is_read() {
    let text = format!("\u{feff}\"t_s\",\"theta_fb_rad\",\"i_q_a\"\n{}", body(6000));
    assert_eq!(parse(&text).unwrap().len(), 6000);
}

#[test]
fn a_huge_angle_is_refused_instead_of_turning_the_torque_current_into_nan() {
    // Found by fuzzing: θ = 1.5e307 made Nr·θ overflow, sin(inf) = NaN, and i_q NaN.
    let text = "t_s,theta_fb_rad,i_a_a,i_b_a\n0,0,0.5,-0.5\n0.001,0.150000000000000021e308,0.5,-0.5\n";
    let e = parse(text).unwrap_err().to_string();
    assert!(e.contains("run.csv: line 3, column 'theta_fb_rad'") && e.contains("1e9"), "{e}");
}

#[test]
fn the_d_current_is_read_from_its_column_else_parked_from_the_phase_currents() {
    // A current vector of 0.3 A along d and 0.2 A along q at θe = 50·θ.
    let rows = |with: &dyn Fn(f64, f64, f64) -> String| -> String {
        (0..6000)
            .map(|i| {
                let (t, th) = (i as f64 * 5e-5, i as f64 * 5e-5);
                let (s, c) = (50.0 * th).sin_cos();
                with(t, th, 0.3 * c - 0.2 * s) + &format!(",{}\n", 0.3 * s + 0.2 * c)
            })
            .collect()
    };
    let phases = format!("t_s,theta_fb_rad,i_a_a,i_b_a\n{}", rows(&|t, th, ia| format!("{t},{th},{ia}")));
    let log = parse(&phases).unwrap();
    let (id, iq) = (log.i_d_a.as_ref().unwrap(), &log.i_q_a);
    assert!(id.iter().all(|d| (d - 0.3).abs() < 1e-12) && iq.iter().all(|q| (q - 0.2).abs() < 1e-12));
    // With i_q_a given too: i_d from the phase currents still.
    let both = format!("t_s,theta_fb_rad,i_q_a,i_a_a,i_b_a\n{}", rows(&|t, th, ia| format!("{t},{th},0.2,{ia}")));
    assert!(parse(&both).unwrap().i_d_a.unwrap().iter().all(|d| (d - 0.3).abs() < 1e-12));
    // The column wins over the phases.
    let column =
        format!("t_s,theta_fb_rad,i_q_a,i_d_a,i_a_a,i_b_a\n{}", rows(&|t, th, ia| format!("{t},{th},0.2,0.25,{ia}")));
    assert!(parse(&column).unwrap().i_d_a.unwrap().iter().all(|&d| d == 0.25));
    // Neither: None (i_d = 0 is assumed by the fit).
    assert!(parse(&format!("{HEAD}{}", body(6000))).unwrap().i_d_a.is_none());
}
