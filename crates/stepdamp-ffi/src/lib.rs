//! # stepdamp-ffi
//!
//! The `stepdamp-core` controller as a C library (`libstepdamp_ffi.a`, header
//! `include/stepdamp.h`, generated from this crate by cbindgen). Plain `#[repr(C)]`
//! structs, fixed capacity, no allocation, no callbacks.
//!
//! Usage from C: fill an `sd_params` (or start from `sd_params_patent_motor()`), call
//! `sd_config_init()` once, `sd_state_init()` once, then per PWM period
//! `sd_command_speed()` (when the command changes) and `sd_step()`.
//!
//! Rules of the boundary:
//! - every function returns an `sd_status` (except the two pure helpers that take no
//!   pointer); a NULL pointer is [`SD_ERR_NULL_POINTER`], never a crash;
//! - every rejected parameter has its own status code; `sd_status_str()` names it;
//! - enums arrive as integers and are validated (C may pass any value);
//! - nothing panics: the core never panics on any input, this layer neither indexes nor
//!   unwraps. On bare metal the `panic-handler` feature supplies a handler (an endless
//!   loop) for a C firmware; without it a Rust firmware keeps its own. On hosted targets
//!   the library links `std` for its panic runtime and is otherwise `core`-only.
//!
//! Why `unsafe`: C hands over raw pointers; reading and writing through them cannot be
//! checked by the compiler. The workspace forbids `unsafe_code`; this crate denies it and
//! allows it only on the functions below that dereference C pointers, each after a NULL
//! and (for the opaque types) alignment and initialisation check.
#![no_std]
#![allow(non_camel_case_types, reason = "C names: sd_params, sd_status, ... as the header spells them")]

#[cfg(not(target_os = "none"))]
extern crate std;

mod convert;
mod types;

pub use types::*;

use core::ffi::c_char;

use stepdamp_core::{Config, Measurement, Params, Position, State, step, total_ripple};

use convert::{from_output, harmonic_to_c, params_from_c, patent_motor_c, status_of};

/// Reads `*p` after a NULL check.
macro_rules! deref {
    ($p:expr) => {{
        let p = $p;
        if p.is_null() {
            return SD_ERR_NULL_POINTER;
        }
        // SAFETY: non-NULL; the caller promises it points to a valid, initialised object of
        // the pointee type for the duration of the call (the `# Safety` contract).
        unsafe { &*p }
    }};
}

/// Writes `v` to `*p` after a NULL check.
macro_rules! write_out {
    ($p:expr, $v:expr) => {{
        let p = $p;
        if p.is_null() {
            return SD_ERR_NULL_POINTER;
        }
        // SAFETY: non-NULL; the caller promises it points to writable memory of the
        // pointee type. `write` does not read or drop the old contents.
        unsafe { p.write($v) };
    }};
}

/// The configuration in `*cfg`, or the status why it cannot be used.
///
/// # Safety
/// `cfg` is NULL or points to `SD_CONFIG_SIZE` readable bytes.
#[allow(unsafe_code)]
unsafe fn config_ref<'a>(cfg: *const sd_config) -> Result<&'a Config, sd_status> {
    if cfg.is_null() {
        return Err(SD_ERR_NULL_POINTER);
    }
    if !cfg.cast::<ConfigSlot>().is_aligned() {
        return Err(SD_ERR_MISALIGNED);
    }
    let slot = cfg.cast::<ConfigSlot>();
    // SAFETY: non-NULL, aligned, and the caller promises SD_CONFIG_SIZE readable bytes; any
    // bit pattern is a valid u64.
    let tag = unsafe { core::ptr::addr_of!((*slot).tag).read() };
    if tag != CONFIG_TAG {
        return Err(SD_ERR_NOT_INITIALIZED);
    }
    // SAFETY: the tag is only ever written by `sd_config_init` together with a valid
    // `Config` (and cleared when initialisation fails).
    Ok(unsafe { &(*slot).config })
}

/// The state slot at `st` after the NULL, alignment and tag checks.
///
/// # Safety
/// `st` is NULL or points to `SD_STATE_SIZE` readable bytes.
#[allow(unsafe_code)]
unsafe fn state_slot(st: *const sd_state) -> Result<*const StateSlot, sd_status> {
    if st.is_null() {
        return Err(SD_ERR_NULL_POINTER);
    }
    let slot = st.cast::<StateSlot>();
    if !slot.is_aligned() {
        return Err(SD_ERR_MISALIGNED);
    }
    // SAFETY: non-NULL, aligned, SD_STATE_SIZE bytes by the caller's promise; any bit
    // pattern is a valid u64.
    let tag = unsafe { core::ptr::addr_of!((*slot).tag).read() };
    if tag != STATE_TAG {
        return Err(SD_ERR_NOT_INITIALIZED);
    }
    Ok(slot)
}

/// The state in `*st` for reading, or the status why it cannot be used.
///
/// # Safety
/// `st` is NULL or points to `SD_STATE_SIZE` readable bytes.
#[allow(unsafe_code)]
unsafe fn state_ref<'a>(st: *const sd_state) -> Result<&'a State, sd_status> {
    // SAFETY: forwarded caller contract; the tag is only written by `sd_state_init`
    // together with a valid `State`.
    unsafe { state_slot(st).map(|slot| &(*slot).state) }
}

/// The state in `*st` for writing, or the status why it cannot be used.
///
/// # Safety
/// `st` is NULL or points to `SD_STATE_SIZE` writable bytes not aliased during the call.
#[allow(unsafe_code)]
unsafe fn state_mut<'a>(st: *mut sd_state) -> Result<&'a mut State, sd_status> {
    // SAFETY: as `state_ref`; the pointer came in as `*mut` (writable) and the caller
    // promises no aliasing during the call.
    unsafe { state_slot(st).map(|slot| &mut (*slot.cast_mut()).state) }
}

/// Fills `*out` with the parameters of the reference `patent-motor` (Km 0.3 N·m/A, Nr 50,
/// 0.9 Ω, 2.5 mH, 48 V three-leg stage at 20 kHz, one-period delay, 1.9 A holding, 3 A
/// limit, 1.5 kHz current loop, 4000-count encoder, 50 Hz servo loop, three detent
/// harmonics) in `mode` (`SD_MODE_*`) with `compensation` (`SD_COMPENSATION_*`): the
/// same numbers as the Rust `Params::patent_motor`. `out->motor.detent` points to a
/// table inside the library (static, read-only).
///
/// # Safety
/// `out` is NULL or points to a writable `sd_params`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_params_patent_motor(
    mode: sd_mode,
    compensation: sd_compensation,
    out: *mut sd_params,
) -> sd_status {
    match patent_motor_c(mode, compensation) {
        Ok(p) => {
            write_out!(out, p);
            SD_OK
        }
        Err(s) => s,
    }
}

/// Validates `*params` and writes the precomputed configuration into `*cfg` (call once at
/// start-up; it evaluates sin/cos and square roots, not meant for the control interrupt).
/// On any error `*cfg` is marked uninitialised and the status names the first offending
/// parameter (`SD_ERR_KM`, `SD_ERR_BUS_VOLTAGE`, ...).
///
/// # Safety
/// `params` is NULL or points to a readable `sd_params` whose `motor.detent` is NULL or
/// points to `motor.detent_count` readable `sd_harmonic`s (and likewise
/// `motor.ripple_per_amp_d`, `motor.ripple_per_amp_q` with their counts); `cfg` is NULL or points to a
/// writable `sd_config`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_config_init(params: *const sd_params, cfg: *mut sd_config) -> sd_status {
    if cfg.is_null() {
        return SD_ERR_NULL_POINTER;
    }
    let slot = cfg.cast::<ConfigSlot>();
    if !slot.is_aligned() {
        return SD_ERR_MISALIGNED;
    }
    // SAFETY: non-NULL and aligned; the caller promises SD_CONFIG_SIZE writable bytes.
    // Cleared first so that a failed initialisation leaves an unusable config.
    unsafe { core::ptr::addr_of_mut!((*slot).tag).write(0) };
    let p = deref!(params);
    let mut tables = [[stepdamp_core::Harmonic::default(); SD_MAX_HARMONICS as usize]; 3];
    // SAFETY: forwarded caller contract (the tables of `*params`).
    let core_params = match unsafe { core_params(p, &mut tables) } {
        Ok(cp) => cp,
        Err(s) => return s,
    };
    match Config::new(&core_params) {
        Ok(config) => {
            // SAFETY: as above; `write` does not drop the (possibly garbage) old contents.
            unsafe { slot.write(ConfigSlot { tag: CONFIG_TAG, config }) };
            SD_OK
        }
        Err(e) => status_of(&e),
    }
}

/// The core's parameters of `*p`, its harmonic tables copied into `tables`, or the status
/// of the first table whose pointer and count disagree, or of a bad enumeration.
///
/// # Safety
/// `p.motor.detent`, `p.motor.ripple_per_amp_d` and `p.motor.ripple_per_amp_q` are NULL or
/// point to their count of readable `sd_harmonic`s.
#[allow(unsafe_code)]
unsafe fn core_params<'t>(p: &sd_params, tables: &'t mut convert::Tables) -> Result<Params<'t>, sd_status> {
    let m = &p.motor;
    let detent_errors =
        (SD_ERR_DETENT_COUNT_BEYOND_CAPACITY, SD_ERR_DETENT_NULL_WITH_COUNT, SD_ERR_DETENT_POINTER_WITHOUT_COUNT);
    let ripple_errors = (SD_ERR_RIPPLE_TABLE, SD_ERR_RIPPLE_TABLE, SD_ERR_RIPPLE_TABLE);
    // SAFETY: the caller promises each pointer is NULL or points to its count of readable
    // harmonics (the function's safety section).
    let harmonics = unsafe {
        [
            c_table(m.detent, m.detent_count, detent_errors)?,
            c_table(m.ripple_per_amp_d, m.ripple_per_amp_d_count, ripple_errors)?,
            c_table(m.ripple_per_amp_q, m.ripple_per_amp_q_count, ripple_errors)?,
        ]
    };
    params_from_c(p, harmonics, tables)
}

/// A C table of `count` harmonics at `ptr` as a slice; the statuses for a count beyond
/// `SD_MAX_HARMONICS`, NULL with a count, and a pointer with a count of 0.
///
/// # Safety
/// `ptr` is NULL or points to `count` readable `sd_harmonic`s.
#[allow(unsafe_code)]
unsafe fn c_table<'a>(
    ptr: *const sd_harmonic,
    count: u32,
    (beyond, null_with_count, pointer_without_count): (sd_status, sd_status, sd_status),
) -> Result<&'a [sd_harmonic], sd_status> {
    if count > SD_MAX_HARMONICS {
        Err(beyond)
    } else if count > 0 && ptr.is_null() {
        Err(null_with_count)
    } else if count == 0 && !ptr.is_null() {
        Err(pointer_without_count)
    } else if count == 0 {
        Ok(&[])
    } else {
        // SAFETY: non-NULL, count ≤ SD_MAX_HARMONICS, and the caller promises that many
        // readable harmonics.
        Ok(unsafe { core::slice::from_raw_parts(ptr, count as usize) })
    }
}

/// The total ripple torque on the rotor of the motor in `*params` at rotor-frame currents
/// `i_d_a`, `i_q_a` (A): the detent plus the ripple that grows with the current
/// (`motor.ripple_per_amp_d`, `motor.ripple_per_amp_q`), harmonic by harmonic in the detent's
/// convention (torque on the rotor `−A sin(k·θe + φ)`, `amplitude_nm` in N·m > 0, `phase_rad`
/// in (−π, π]), ascending orders, orders whose total is 0 left out: at most
/// `SD_MAX_HARMONIC_ORDER`. Open loop at the holding current is `(holding_current_a, 0)`, a
/// servo `(0, i_q)`. What `stepdamp motor ripple --id A --iq A` prints as its total, in
/// `f32` (docs/c.md).
///
/// `*params` is validated as `sd_config_init()` validates it (the same statuses; like it,
/// a start-up call: its stack holds a configuration). A non-finite current, or a current
/// vector beyond `drive.current_limit_a`, is `SD_ERR_OPERATING_CURRENT`. On `SD_OK` or
/// `SD_ERR_CAPACITY_TOO_SMALL`, `*count` is the number of harmonics (on any other status 0,
/// unless `count` is NULL); `out[0 .. *count]` is written only when `capacity >= *count`.
/// `out` may be NULL with a `capacity` of 0 to ask for the count.
///
/// # Safety
/// `params` as for `sd_config_init()`; `out` is NULL or points to `capacity` writable
/// `sd_harmonic`s; `count` is NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_motor_ripple(
    params: *const sd_params,
    i_d_a: f32,
    i_q_a: f32,
    out: *mut sd_harmonic,
    capacity: u32,
    count: *mut u32,
) -> sd_status {
    write_out!(count, 0);
    let p = deref!(params);
    if out.is_null() && capacity > 0 {
        return SD_ERR_NULL_POINTER;
    }
    let mut tables = [[stepdamp_core::Harmonic::default(); SD_MAX_HARMONICS as usize]; 3];
    // SAFETY: forwarded caller contract (the tables of `*params`).
    let core_params = match unsafe { core_params(p, &mut tables) } {
        Ok(cp) => cp,
        Err(s) => return s,
    };
    if let Err(e) = Config::new(&core_params) {
        return status_of(&e);
    }
    let total = match total_ripple(&core_params.motor, core_params.drive.current_limit_a, i_d_a, i_q_a) {
        Ok(t) => t,
        Err(e) => return status_of(&e),
    };
    let harmonics = total.harmonics();
    // At most MAX_HARMONIC_ORDER = 32: the cast is exact.
    write_out!(count, harmonics.len() as u32);
    if harmonics.len() > capacity as usize {
        return SD_ERR_CAPACITY_TOO_SMALL;
    }
    for (i, h) in harmonics.iter().enumerate() {
        // SAFETY: `out` is non-NULL here (capacity ≥ len > 0 when the loop runs), and the
        // caller promises `capacity` writable harmonics; i < len ≤ capacity.
        unsafe { out.add(i).write(harmonic_to_c(*h)) };
    }
    SD_OK
}

/// Sets `*st` to the start state: rotor and command at position 0, speed 0, no faults.
///
/// # Safety
/// `st` is NULL or points to a writable `sd_state`.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_state_init(st: *mut sd_state) -> sd_status {
    let slot = st.cast::<StateSlot>();
    if !slot.is_null() && !slot.is_aligned() {
        return SD_ERR_MISALIGNED;
    }
    write_out!(slot, StateSlot { tag: STATE_TAG, state: State::default() });
    SD_OK
}

/// Sets the commanded speed in rad/s (mechanical), clamped to ±`max_speed_rad_s` of
/// `sd_config_info`; a non-finite speed is ignored (the previous command stays).
///
/// # Safety
/// `cfg` and `st` are NULL or point to objects initialised by `sd_config_init()` and
/// `sd_state_init()`; `st` is not accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_command_speed(cfg: *const sd_config, st: *mut sd_state, speed_rad_s: f32) -> sd_status {
    // SAFETY: forwarded caller contract.
    let (cfg, st) = match unsafe { (config_ref(cfg), state_mut(st)) } {
        (Ok(c), Ok(s)) => (c, s),
        (Err(e), _) | (_, Err(e)) => return e,
    };
    st.command_speed(cfg, speed_rad_s);
    SD_OK
}

/// Runs one control period: takes the samples in `*m`, advances `*st`, and writes the leg
/// duties (and internal signals) to `*out`. Call once per PWM period. Bounded time, no
/// allocation, never fails on any sample value (a non-finite or absurd current sample is
/// counted in `sample_faults` and replaced; see `sd_state_info`).
///
/// # Safety
/// `cfg` and `st` are NULL or initialised (see `sd_command_speed`); `m` is NULL or
/// readable; `out` is NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_step(
    cfg: *const sd_config,
    st: *mut sd_state,
    m: *const sd_measurement,
    out: *mut sd_output,
) -> sd_status {
    // SAFETY: forwarded caller contract.
    let (cfg, st) = match unsafe { (config_ref(cfg), state_mut(st)) } {
        (Ok(c), Ok(s)) => (c, s),
        (Err(e), _) | (_, Err(e)) => return e,
    };
    let m = deref!(m);
    if out.is_null() {
        return SD_ERR_NULL_POINTER;
    }
    let o = step(cfg, st, &Measurement { i_a_a: m.i_a_a, i_b_a: m.i_b_a, encoder_count: m.encoder_count });
    write_out!(out, from_output(&o));
    SD_OK
}

/// Copies faults, commands and observer estimates of `*st` into `*out`.
///
/// # Safety
/// `st` is NULL or initialised; `out` is NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_state_read(st: *const sd_state, out: *mut sd_state_info) -> sd_status {
    // SAFETY: forwarded caller contract.
    let st = match unsafe { state_ref(st) } {
        Ok(s) => s,
        Err(e) => return e,
    };
    write_out!(
        out,
        sd_state_info {
            position_command: st.position_command().0,
            speed_command_rad_s: st.speed_command_rad_s(),
            sample_faults: st.sample_faults,
            current_sensor_fault: st.current_sensor_fault(),
            observer_r_hat_ohm: st.observer.r_hat_ohm,
            observer_km_hat: st.observer.km_hat,
            observer_delta_rad: st.observer.delta_rad,
        }
    );
    SD_OK
}

/// Copies derived facts of `*cfg` (period, speed limit, legs, ...) into `*out`.
///
/// # Safety
/// `cfg` is NULL or initialised; `out` is NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_config_read(cfg: *const sd_config, out: *mut sd_config_info) -> sd_status {
    // SAFETY: forwarded caller contract.
    let cfg = match unsafe { config_ref(cfg) } {
        Ok(c) => c,
        Err(e) => return e,
    };
    write_out!(out, convert::config_info(cfg));
    SD_OK
}

/// The average winding voltages, as fractions of the bus voltage, that the duties of
/// `*o` make on the power stage of `*cfg` (`*u_a`, `*u_b` in [−1, 1]): what a plant model
/// or a test bench applies to the windings.
///
/// # Safety
/// `cfg` is NULL or initialised; `o` is NULL or readable; `u_a`, `u_b` NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_winding_voltages_per_vdc(
    cfg: *const sd_config,
    o: *const sd_output,
    u_a: *mut f32,
    u_b: *mut f32,
) -> sd_status {
    // SAFETY: forwarded caller contract.
    let cfg = match unsafe { config_ref(cfg) } {
        Ok(c) => c,
        Err(e) => return e,
    };
    let o = deref!(o);
    if u_b.is_null() {
        return SD_ERR_NULL_POINTER;
    }
    let (a, b) = cfg.topology().winding_voltages_per_vdc(&stepdamp_core::LegDuties(o.duties));
    write_out!(u_a, a);
    write_out!(u_b, b);
    SD_OK
}

/// Electrical angle in rad, in [−π, π], of a position in units of 2⁻³² electrical
/// revolution (`sd_output.theta_cmd`, `sd_state_info.position_command`).
#[allow(unsafe_code, reason = "an exported C symbol (no_mangle) is unsafe by definition")]
#[unsafe(no_mangle)]
pub extern "C" fn sd_position_electrical_angle_rad(position: i64) -> f32 {
    Position(position).electrical_angle_rad()
}

/// `expf` of the library's libm (the Rust `libm` crate). For C test benches that must
/// reproduce a Rust simulation bit for bit; a firmware does not need it.
#[allow(unsafe_code, reason = "an exported C symbol (no_mangle) is unsafe by definition")]
#[unsafe(no_mangle)]
pub extern "C" fn sd_ref_expf(x: f32) -> f32 {
    libm::expf(x)
}

/// `sincosf` of the library's libm: `*s = sin x`, `*c = cos x` (see `sd_ref_expf`).
///
/// # Safety
/// `s` and `c` are NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sd_ref_sincosf(x: f32, s: *mut f32, c: *mut f32) -> sd_status {
    if s.is_null() || c.is_null() {
        return SD_ERR_NULL_POINTER;
    }
    let (sin, cos) = libm::sincosf(x);
    write_out!(s, sin);
    write_out!(c, cos);
    SD_OK
}

/// A static, NUL-terminated English description of `status` (never NULL; unknown codes
/// give "unknown status").
#[allow(unsafe_code, reason = "an exported C symbol (no_mangle) is unsafe by definition")]
#[unsafe(no_mangle)]
pub extern "C" fn sd_status_str(status: sd_status) -> *const c_char {
    convert::status_text(status).as_ptr()
}

#[cfg(test)]
mod tests;

/// The bare-metal panic handler of a C firmware (feature `panic-handler`): nothing in
/// this library panics on any input, so reaching it means a bug; it stops in an endless
/// loop (a watchdog then resets the drive) rather than unwinding into C.
#[cfg(all(feature = "panic-handler", target_os = "none"))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
