//! The C-visible types: plain `#[repr(C)]` structs, integer enums with `#define`d values
//! (C may pass any integer, so every enum is an integer the library validates), status
//! codes, and the opaque, fixed-size storage for the configuration and the state.

use core::mem::{align_of, size_of};

use stepdamp_core::{Config, State};

/// Result of every call: [`SD_OK`] (0) or one of the `SD_ERR_*` codes, each for exactly
/// one cause. `sd_status_str()` names it.
pub type sd_status = i32;

/// Success.
pub const SD_OK: sd_status = 0;
/// A pointer argument was NULL.
pub const SD_ERR_NULL_POINTER: sd_status = 1;
/// An `sd_config` or `sd_state` was not initialised by `sd_config_init()` /
/// `sd_state_init()` (or its initialisation failed).
pub const SD_ERR_NOT_INITIALIZED: sd_status = 2;
/// An `sd_config` or `sd_state` is not aligned to 8 bytes.
pub const SD_ERR_MISALIGNED: sd_status = 3;
/// `params.mode` is not one of the `SD_MODE_*` values.
pub const SD_ERR_INVALID_MODE: sd_status = 4;
/// `params.compensation` is not one of the `SD_COMPENSATION_*` values.
pub const SD_ERR_INVALID_COMPENSATION: sd_status = 5;
/// `params.drive.topology` is not one of the `SD_TOPOLOGY_*` values.
pub const SD_ERR_INVALID_TOPOLOGY: sd_status = 6;
/// `params.motor.detent_count` exceeds `SD_MAX_HARMONICS`.
pub const SD_ERR_DETENT_COUNT_BEYOND_CAPACITY: sd_status = 7;
/// `params.motor.detent` is NULL while `detent_count` > 0.
pub const SD_ERR_DETENT_NULL_WITH_COUNT: sd_status = 8;
/// `params.motor.detent` is not NULL while `detent_count` is 0 (a table given but not
/// counted: set the count, or pass NULL for no detent compensation).
pub const SD_ERR_DETENT_POINTER_WITHOUT_COUNT: sd_status = 9;
/// A detent harmonic order is outside `1..=SD_MAX_HARMONIC_ORDER`.
pub const SD_ERR_HARMONIC_ORDER: sd_status = 10;
/// The same detent harmonic order is given twice.
pub const SD_ERR_DUPLICATE_HARMONIC: sd_status = 11;
/// `motor.km_nm_per_a` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_KM: sd_status = 12;
/// `motor.pole_pairs` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_POLE_PAIRS: sd_status = 13;
/// `motor.resistance_ohm` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_RESISTANCE: sd_status = 14;
/// `motor.inductance_h` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_INDUCTANCE: sd_status = 15;
/// `motor.coulomb_friction_nm` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_COULOMB_FRICTION: sd_status = 16;
/// `drive.bus_voltage_v` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_BUS_VOLTAGE: sd_status = 17;
/// `drive.pwm_hz` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_PWM_FREQUENCY: sd_status = 18;
/// `drive.current_limit_a` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_CURRENT_LIMIT: sd_status = 19;
/// `drive.holding_current_a` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_HOLDING_CURRENT: sd_status = 20;
/// `drive.current_loop_bandwidth_hz` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_CURRENT_LOOP_BANDWIDTH: sd_status = 21;
/// `drive.computation_delay_periods` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_COMPUTATION_DELAY: sd_status = 22;
/// `encoder_counts_per_rev` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_ENCODER_COUNTS: sd_status = 23;
/// `servo.velocity_nm_s_per_rad` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_SERVO_VELOCITY_GAIN: sd_status = 24;
/// `servo.position_nm_per_rad` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_SERVO_POSITION_GAIN: sd_status = 25;
/// `servo.position_integral_nm_per_rad_s` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_SERVO_INTEGRAL_GAIN: sd_status = 26;
/// `servo.velocity_filter_hz` is outside the range the core enforces (`sd_status_str()` states it).
pub const SD_ERR_SERVO_VELOCITY_FILTER: sd_status = 27;
/// A detent amplitude is outside its range, or the amplitudes sum to the holding torque
/// `Km·I_hold` or more (`sd_status_str()` states both bounds).
pub const SD_ERR_DETENT_AMPLITUDE: sd_status = 28;
/// A detent phase is outside its range (`sd_status_str()` states it).
pub const SD_ERR_DETENT_PHASE: sd_status = 29;
/// A parameter this version of the C API has no dedicated code for was rejected by the
/// core (a newer check); the Rust `ConfigError` names it.
pub const SD_ERR_INVALID_PARAMETER: sd_status = 30;
/// A current-ripple table (`motor.ripple_per_amp_d`, `motor.ripple_per_amp_q`) has more than
/// `SD_MAX_HARMONICS` entries, or its pointer and count disagree (NULL with a count, or a
/// pointer with a count of 0).
pub const SD_ERR_RIPPLE_TABLE: sd_status = 31;
/// A current-ripple amplitude (N·m/A) is outside its range (`sd_status_str()` states it).
pub const SD_ERR_RIPPLE_AMPLITUDE: sd_status = 32;
/// A current-ripple phase is outside its range (`sd_status_str()` states it).
pub const SD_ERR_RIPPLE_PHASE: sd_status = 33;
/// `sd_motor_ripple()`: `i_d_a` or `i_q_a` is not finite, or the current vector is beyond
/// `drive.current_limit_a` (each component and its magnitude).
pub const SD_ERR_OPERATING_CURRENT: sd_status = 34;
/// `sd_motor_ripple()`: `capacity` is smaller than the number of harmonics to write (`*count`
/// says how many; nothing is written to `out`).
pub const SD_ERR_CAPACITY_TOO_SMALL: sd_status = 35;

/// Control mode (`SD_MODE_*`).
pub type sd_mode = u32;
/// Microstepping without an encoder (patent eqs. 7–8).
pub const SD_MODE_OPEN_LOOP: sd_mode = 0;
/// Position servo on the encoder (patent eqs. 14–15).
pub const SD_MODE_SERVO: sd_mode = 1;

/// Detent compensation (`SD_COMPENSATION_*`).
pub type sd_compensation = u32;
/// None (and no friction feed-forward in servo mode).
pub const SD_COMPENSATION_OFF: sd_compensation = 0;
/// The patent's law at `θ_cmd` (open loop) or `θ_fb` (servo, with friction feed-forward).
pub const SD_COMPENSATION_PATENT: sd_compensation = 1;
/// Open loop: at the angle estimated by the load-angle observer. Servo: as PATENT.
pub const SD_COMPENSATION_ESTIMATED: sd_compensation = 2;
/// Open loop: rotate the current vector by the correction angle Δ(θ_cmd) at constant
/// magnitude (what Prusa's phase stepping and a microstep table do).
pub const SD_COMPENSATION_ANGLE: sd_compensation = 3;
/// Open loop: replay a drive's correction table. The C API has no way to pass the table
/// yet, so `sd_config_init` refuses it (`SD_ERR_INVALID_PARAMETER`).
pub const SD_COMPENSATION_TABLE: sd_compensation = 4;

/// Power stage (`SD_TOPOLOGY_*`).
pub type sd_topology = u32;
/// Three legs with a shared leg γ: duties `[α, β, γ, 0]`.
pub const SD_TOPOLOGY_THREE_LEG: sd_topology = 0;
/// Two full H-bridges: duties `[A+, A−, B+, B−]`.
pub const SD_TOPOLOGY_TWO_H_BRIDGE: sd_topology = 1;

/// Most detent harmonics a configuration holds (one per order `1..=SD_MAX_HARMONIC_ORDER`).
pub const SD_MAX_HARMONICS: u32 = 32;
/// Highest detent harmonic order (the core's `MAX_HARMONIC_ORDER`; asserted below).
pub const SD_MAX_HARMONIC_ORDER: u32 = 32;

/// One detent harmonic: torque on the rotor `−A sin(k·Nr·θ + φ)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct sd_harmonic {
    /// Order `k` (multiple of the electrical angle), 1..=`SD_MAX_HARMONIC_ORDER`.
    pub order: u16,
    /// Amplitude `A` in N·m (≥ 0).
    pub amplitude_nm: f32,
    /// Phase `φ` in rad.
    pub phase_rad: f32,
}

/// What the controller knows of the motor (SI units).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sd_motor {
    /// Torque constant `Km` in N·m/A (range: `sd_status_str(SD_ERR_KM)`).
    pub km_nm_per_a: f32,
    /// Rotor teeth / pole pairs `Nr` (50 for a 1.8° motor; range: `sd_status_str(SD_ERR_POLE_PAIRS)`).
    pub pole_pairs: u16,
    /// Phase resistance `R` in Ω (range: `sd_status_str(SD_ERR_RESISTANCE)`).
    pub resistance_ohm: f32,
    /// Phase inductance `L` in H (range: `sd_status_str(SD_ERR_INDUCTANCE)`).
    pub inductance_h: f32,
    /// Coulomb friction `Fs` in N·m (≥ 0), fed forward in servo mode.
    pub coulomb_friction_nm: f32,
    /// Detent harmonics (`detent_count` of them; read only during `sd_config_init()`,
    /// which copies them, and `sd_motor_ripple()`), or NULL with a count of 0.
    pub detent: *const sd_harmonic,
    /// Number of harmonics at `detent`, 0..=`SD_MAX_HARMONICS`.
    pub detent_count: u32,
    /// The ripple that grows with the current (a real motor's flux harmonics and phase
    /// imbalance, docs/design.md#real-motors-flux-harmonics): its part per ampere of `i_d`,
    /// `amplitude_nm` in N·m/A (what `stepdamp motor ripple --format json` gives as the
    /// profile's parts; `export c-header` writes it), or NULL with a count of 0 for a
    /// pure-sine motor. Read only during `sd_config_init()` and `sd_motor_ripple()`.
    pub ripple_per_amp_d: *const sd_harmonic,
    /// Number of harmonics at `ripple_per_amp_d`, 0..=`SD_MAX_HARMONICS`.
    pub ripple_per_amp_d_count: u32,
    /// Its part per ampere of `i_q` without its mean (the mean is `Km`), N·m/A, or NULL with
    /// a count of 0.
    pub ripple_per_amp_q: *const sd_harmonic,
    /// Number of harmonics at `ripple_per_amp_q`, 0..=`SD_MAX_HARMONICS`.
    pub ripple_per_amp_q_count: u32,
}

/// Power stage and current loop settings.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sd_drive {
    /// DC bus voltage in V (range: `sd_status_str(SD_ERR_BUS_VOLTAGE)`).
    pub bus_voltage_v: f32,
    /// Control and PWM frequency in Hz (20 kHz typical; range: `sd_status_str(SD_ERR_PWM_FREQUENCY)`): `sd_step()` runs once per period.
    pub pwm_hz: f32,
    /// Open-loop d-axis holding current in A (≥ 0, ≤ `current_limit_a`).
    pub holding_current_a: f32,
    /// Limit of the current vector magnitude in A (range: `sd_status_str(SD_ERR_CURRENT_LIMIT)`).
    pub current_limit_a: f32,
    /// Closed current-loop bandwidth in Hz (range: `sd_status_str(SD_ERR_CURRENT_LOOP_BANDWIDTH)`).
    pub current_loop_bandwidth_hz: f32,
    /// Power stage, an `SD_TOPOLOGY_*` value.
    pub topology: sd_topology,
    /// Periods between sampling and the duties taking effect: 0 or 1 (most drives: 1).
    pub computation_delay_periods: u8,
}

/// Servo-mode gains (patent eq. 15) in torque units; the law divides them by `Km`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sd_servo {
    /// `Kp_vel` in N·m·s/rad (≥ 0).
    pub velocity_nm_s_per_rad: f32,
    /// `Kp_pos` in N·m/rad (≥ 0).
    pub position_nm_per_rad: f32,
    /// `Ki_pos` in N·m/(rad·s) (≥ 0).
    pub position_integral_nm_per_rad_s: f32,
    /// Corner of the encoder velocity low-pass filter in Hz (range:
    /// `sd_status_str(SD_ERR_SERVO_VELOCITY_FILTER)`).
    pub velocity_filter_hz: f32,
}

/// Everything the controller is configured with (the Rust `stepdamp_core::Params`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sd_params {
    /// Motor model.
    pub motor: sd_motor,
    /// Drive settings.
    pub drive: sd_drive,
    /// Encoder counts per mechanical revolution (used in servo mode; range:
    /// `sd_status_str(SD_ERR_ENCODER_COUNTS)`).
    pub encoder_counts_per_rev: u32,
    /// Servo gains (used in servo mode).
    pub servo: sd_servo,
    /// An `SD_MODE_*` value.
    pub mode: sd_mode,
    /// An `SD_COMPENSATION_*` value.
    pub compensation: sd_compensation,
}

/// What the drive samples at the start of a period.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sd_measurement {
    /// Phase A current in A (positive from leg α / A+ into winding A).
    pub i_a_a: f32,
    /// Phase B current in A (positive from leg β / B+ into winding B).
    pub i_b_a: f32,
    /// Raw free-running encoder counter (wrapping; counts up for positive rotation; 0 at
    /// power-on with the rotor at θ = 0). Leave 0 without an encoder (open loop).
    pub encoder_count: u32,
}

/// Result of one period.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sd_output {
    /// Leg duties in [0, 1] to load into the PWM timer: three legs `[α, β, γ, 0]`, two
    /// H-bridges `[A+, A−, B+, B−]`.
    pub duties: [f32; 4],
    /// Commanded position used this period, in units of 2⁻³² electrical revolution.
    pub theta_cmd: i64,
    /// Encoder position, in units of 2⁻³² electrical revolution.
    pub theta_fb: i64,
    /// Filtered encoder velocity in rad/s (mechanical).
    pub omega_fb_rad_s: f32,
    /// Measured d current in the controller's frame, A.
    pub i_d_a: f32,
    /// Measured q current in the controller's frame, A.
    pub i_q_a: f32,
    /// d current command, A.
    pub i_d_cmd_a: f32,
    /// q (torque) current command, A.
    pub i_q_cmd_a: f32,
    /// Applied winding A voltage after limiting, V.
    pub v_a_v: f32,
    /// Applied winding B voltage after limiting, V.
    pub v_b_v: f32,
    /// Voltage scale applied by the modulator (1 = not limited).
    pub voltage_scale: f32,
}

/// A snapshot of the mutable state a firmware reads (faults, commands, observer).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sd_state_info {
    /// Commanded position of the next period, units of 2⁻³² electrical revolution.
    pub position_command: i64,
    /// Commanded speed in rad/s (mechanical), after clamping.
    pub speed_command_rad_s: f32,
    /// Current samples rejected so far (non-finite or beyond 100× the limit), saturating.
    pub sample_faults: u32,
    /// True while the current sensor is declared faulty (that many rejected samples in a
    /// row that `sd_step()` puts zero volts on the windings); clears on a good sample.
    pub current_sensor_fault: bool,
    /// Observer's resistance estimate R̂ in Ω (0 when the observer is not in use).
    pub observer_r_hat_ohm: f32,
    /// Observer's torque-constant estimate K̂m in N·m/A (0 when not in use).
    pub observer_km_hat: f32,
    /// Observer's load-angle estimate δ̂ in rad (electrical).
    pub observer_delta_rad: f32,
}

/// Derived facts of a configuration.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sd_config_info {
    /// Control period `Ts` in s.
    pub period_s: f32,
    /// Largest commanded speed magnitude in rad/s; `sd_command_speed()` clamps to it.
    pub max_speed_rad_s: f32,
    /// Nominal bus voltage in V.
    pub bus_voltage_v: f32,
    /// Rotor pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Legs used in `sd_output.duties` (3 or 4).
    pub legs: u32,
    /// `SD_MODE_*`.
    pub mode: sd_mode,
    /// `SD_TOPOLOGY_*`.
    pub topology: sd_topology,
}

/// Bytes of an `sd_config`. The configuration uses about 8.6 kB today (on x86-64 and
/// Cortex-M alike: no pointers inside), 8,192 B of it the drive-replay correction table of
/// the `table` law (1024 ticks × 2 windings × 2 directions × `int16_t`); the rest is
/// headroom so the layout can grow without changing what C allocates. A test keeps at
/// least a quarter of it free.
pub const SD_CONFIG_SIZE: usize = 16384;
/// Bytes of an `sd_state` (168 used today), with headroom like `SD_CONFIG_SIZE`.
pub const SD_STATE_SIZE: usize = 512;
/// `SD_CONFIG_SIZE` in 8-byte words (the storage is `uint64_t` for its alignment).
pub const SD_CONFIG_WORDS: usize = SD_CONFIG_SIZE / 8;
/// `SD_STATE_SIZE` in 8-byte words.
pub const SD_STATE_WORDS: usize = SD_STATE_SIZE / 8;

/// Validated, precomputed configuration: opaque, `SD_CONFIG_SIZE` bytes, 8-byte aligned
/// (place it anywhere, statically too). Written by `sd_config_init()`, then read only.
#[repr(C)]
pub struct sd_config {
    /// Opaque storage.
    pub _opaque: [u64; SD_CONFIG_WORDS],
}

/// Controller state: opaque, `SD_STATE_SIZE` bytes, 8-byte aligned. Written by
/// `sd_state_init()`, then by `sd_command_speed()` and `sd_step()`.
#[repr(C)]
pub struct sd_state {
    /// Opaque storage.
    pub _opaque: [u64; SD_STATE_WORDS],
}

/// What the opaque `sd_config` holds: a tag that says it was initialised, and the config.
#[repr(C)]
pub(crate) struct ConfigSlot {
    pub(crate) tag: u64,
    pub(crate) config: Config,
}

/// What the opaque `sd_state` holds.
#[repr(C)]
pub(crate) struct StateSlot {
    pub(crate) tag: u64,
    pub(crate) state: State,
}

/// Tag of an initialised `sd_config` ("SDCONFIG").
pub(crate) const CONFIG_TAG: u64 = u64::from_le_bytes(*b"SDCONFIG");
/// Tag of an initialised `sd_state` ("SDSTATE1").
pub(crate) const STATE_TAG: u64 = u64::from_le_bytes(*b"SDSTATE1");

// The sizes C sees must hold what Rust stores, at the alignment C guarantees (the
// `uint64_t` array: 8 on both AAPCS and x86-64 SysV).
const _: () = assert!(size_of::<ConfigSlot>() <= SD_CONFIG_SIZE);
const _: () = assert!(size_of::<StateSlot>() <= SD_STATE_SIZE);
const _: () = assert!(align_of::<ConfigSlot>() <= align_of::<sd_config>());
const _: () = assert!(align_of::<StateSlot>() <= align_of::<sd_state>());
const _: () = assert!(SD_CONFIG_SIZE % 8 == 0 && SD_STATE_SIZE % 8 == 0);
const _: () = assert!(SD_MAX_HARMONIC_ORDER as usize == stepdamp_core::MAX_HARMONIC_ORDER);
const _: () = assert!(SD_MAX_HARMONICS == SD_MAX_HARMONIC_ORDER);

#[cfg(test)]
mod tests {
    use super::*;

    /// The opaque sizes are fixed ABI; today's contents must leave room to grow without
    /// changing them: at least a quarter of the config (which already holds its largest
    /// member, the correction table) and half of the state are free.
    #[test]
    fn opaque_storage_holds_the_config_and_state_with_room_to_spare() {
        let (c, s) = (size_of::<ConfigSlot>(), size_of::<StateSlot>());
        std::eprintln!("ConfigSlot {c} of {SD_CONFIG_SIZE} B, StateSlot {s} of {SD_STATE_SIZE} B");
        assert!(4 * c <= 3 * SD_CONFIG_SIZE, "ConfigSlot {c} B");
        assert!(2 * s <= SD_STATE_SIZE, "StateSlot {s} B");
    }
}
