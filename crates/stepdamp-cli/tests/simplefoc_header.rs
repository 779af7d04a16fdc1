//! The exported SimpleFOC header, compiled with `c++` against a stand-in for SimpleFOC 2.4.0's
//! `FOCMotor`: the members the header uses, and the set-point arithmetic of `loopFOC` and
//! `move` as read in its `FOCMotor.cpp` (`current_sp = constrain(current_sp) +
//! feed_forward_current.q` in place; `move` skips `motion_downsample` calls out of
//! `motion_downsample + 1`). Written from that reading; none of SimpleFOC's code is here.
//! Skips cleanly only when there is no `c++`.

use std::process::Command;

const STAND_IN: &str = r#"
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
struct DQCurrent_s { float d = 0.0f; float q = 0.0f; };
struct Motor {
    float electrical_angle = 0.0f, shaft_velocity = 4.0f, current_sp = 0.0f, current_limit = 2.0f;
    int pole_pairs = 50;
    unsigned int motion_downsample = 0, motion_cnt = 0;
    uint32_t loopfoc_time_us = 100;
    DQCurrent_s feed_forward_current;
    double shaft_angle = 0.0;
    float target = 0.5f, applied = 0.0f;
    void loopFOC() {
        shaft_angle += shaft_velocity * 1e-4;
        electrical_angle = (float)std::fmod(shaft_angle * pole_pairs, 6.283185307179586);
        float c = current_sp > current_limit ? current_limit : (current_sp < -current_limit ? -current_limit : current_sp);
        current_sp = c + feed_forward_current.q;
        applied = current_sp;
    }
    void move() {
        if (motion_cnt++ < motion_downsample) return;
        motion_cnt = 0;
        current_sp = target;
    }
};
#include "stepdamp_detent.h"
int main() {
    for (unsigned int ds : {0u, 3u}) {
        Motor motor;
        motor.motion_downsample = ds;
        StepdampFeedForward stepdamp_state;
        double worst = 0.0;
        for (int n = 0; n < 20000; ++n) {
            stepdamp_feed_forward(motor, stepdamp_state);
            motor.loopFOC();
            motor.move();
            if (n < 8) continue;
            // The loop's set-point: move()'s target plus the law half a loop past the angle
            // loopFOC just read.
            float ahead = motor.electrical_angle + 0.5f * motor.shaft_velocity * motor.pole_pairs * 1e-4f;
            double err = std::fabs(motor.applied - (motor.target + stepdamp_q_current(ahead)));
            if (err > worst) worst = err;
        }
        std::printf("motion_downsample %u: worst set-point error %.3g A\n", ds, worst);
        if (!(worst < 2e-4)) return 1;
    }
    return 0;
}
"#;

#[test]
fn the_header_assigns_the_feed_forward_at_the_coming_angle_with_motion_downsample() {
    if Command::new("c++").arg("--version").output().is_err() {
        eprintln!("skipped: no c++");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let h = dir.path().join("stepdamp_detent.h");
    let o = Command::new(env!("CARGO_BIN_EXE_stepdamp"))
        .args(["export", "simplefoc", "--motor", "patent-motor", "--out", h.to_str().unwrap(), "--duration", "0"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let src = dir.path().join("t.cpp");
    std::fs::write(&src, STAND_IN).unwrap();
    let exe = dir.path().join("t");
    let o = Command::new("c++")
        .args(["-std=c++11", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(dir.path())
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let run = Command::new(&exe).output().unwrap();
    let out = String::from_utf8_lossy(&run.stdout);
    eprint!("{out}");
    assert!(run.status.success(), "the set-point accumulated or lagged:\n{out}");
}
