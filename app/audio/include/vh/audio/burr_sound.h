#pragma once
/// @file
/// The drilling burr's sound, synthesized (no sample files): a tone whose pitch follows the
/// burr's speed under load and whose level follows the removal rate, with the noise of cutting.
///
/// Model (each constant is a field of BurrSoundModel):
/// - Speed under load: the handpiece's DC motor runs on its linear torque-speed line,
///   n = n0 (1 - T_load / T_stall), n0 the no-load speed (the scene's drill.burr_speed_rpm) and
///   T_stall the stall torque (the steady-state torque-speed line of a permanent-magnet DC
///   motor: Hughes and Drury, "Electric Motors and Drives", 4th ed., 2013, chapter 3; the
///   "speed-torque line" of a micromotor maker's catalogue). The load torque is the tangential cutting force at the burr's
///   radius: T_load = mu |F| r (e / e_ref), mu the ratio of tangential to normal force at the
///   flutes, |F| the force pressing the burr on the material [N], r the burr radius [m], and the
///   material's specific cutting energy e [J/mm^3] (its hardness, MaterialRemoval's model) over a
///   reference e_ref: a harder material takes more torque at the same push. The speed is kept
///   above min_speed_fraction n0 (the motor's controller), and follows its steady value with
///   the motor's mechanical time constant (a first-order lag), so a push bogs the burr down in
///   tens of milliseconds, not at once.
/// - Pitch: a fluted burr strikes the material flutes times a revolution; the fundamental is
///   that tooth-passing frequency, f0 = flutes n / 60 [Hz] (the tooth-passing frequency of
///   milling: Altintas, "Manufacturing Automation", 2nd ed., 2012, chapters 2 and 3). Its
///   harmonics 2 f0 and 3 f0 (faded out towards Nyquist) and the motor's whine at the rotation
///   frequency n / 60 give the timbre; f0 is the loudest partial.
/// - Level: the tone's amplitude rises from idle_level (free running) by cutting_level times
///   q / (q + half_level_rate), q the removal rate [mm^3/s] (saturating), and band-passed noise
///   (the chips and chatter: white noise through a state-variable band-pass around
///   noise_centre_fraction f0, Simper's trapezoidal SVF, which stays smooth while its centre
///   moves; filtered noise for scraping and friction as in Cook, "Real Sound Synthesis for
///   Interactive Applications", 2002) rises with q in the same way.
/// - No clicks: every target (speed, tone level, noise level, the on/off gate) is reached
///   through a one-pole smoother per sample; the oscillators keep their phase across blocks and
///   across pitch changes (phase accumulators, never restarted).
///
/// Units: force [N], hardness [J/mm^3], removal rate [mm^3/s], speed [rpm], frequency [Hz],
/// samples: mono float, nominally in [-1, 1] (the mixer's limiter guarantees it: drill_mixer.h).
/// Threads: one object, one thread (set and render from the same thread, e.g. the GUI's or the
/// headless run's). render() and mixInto() never allocate, throw or lock.

#include <cstdint>
#include <span>

namespace vh::audio {

/// Default output sample rate [Hz].
inline constexpr double kDefaultSampleRate_Hz = 48000.0;

/// What the burr is doing now (one servo tick's state, or the GUI's latest snapshot).
struct BurrState {
  bool on = false;                               ///< The burr spins.
  double force_N = 0.0;                          ///< |F| pressing the burr on what it cuts [N]; 0: free running.
  double specific_energy_J_per_mm3 = 0.0;        ///< Hardness of what it cuts [J/mm^3]; 0 or less: nothing (no load).
  double removal_rate_mm3_per_s = 0.0;           ///< Material removed per second [mm^3/s].
};

/// The sound model's constants (the file comment gives the equations).
struct BurrSoundModel {
  double sample_rate_Hz = kDefaultSampleRate_Hz;  ///< Output rate [Hz], 8 kHz to 384 kHz.
  double nominal_speed_rpm = 80000.0;             ///< No-load speed n0 [rpm] (the scene's drill.burr_speed_rpm), > 0.
  int flutes = 6;                                 ///< Cutting flutes of the burr (1 to 64): f0 = flutes n / 60.
  double burr_radius_m = 0.0025;                  ///< Burr radius r [m], > 0: the load torque's lever.
  double friction_coefficient = 0.2;              ///< mu: tangential over normal force at the flutes, >= 0.
  /// Stall torque of the motor at the burr [N*m], > 0 (an otologic high-speed motor's ten or so mN*m).
  double stall_torque_Nm = 0.01;
  /// e_ref [J/mm^3], > 0: the hardness at which the load torque is mu |F| r (cancellous bone's default).
  double reference_hardness_J_per_mm3 = 0.6;
  double min_speed_fraction = 0.1;                ///< Lowest speed under load, a fraction of n0 in (0, 1].
  /// The speed's first-order lag behind its steady value [s] (the motor's mechanical time
  /// constant); 0: at once (clicks: for tests).
  double mechanical_time_constant_s = 0.015;
  double level_time_constant_s = 0.005;           ///< Smoothing of the levels [s]; 0: at once (clicks).
  double gate_time_constant_s = 0.02;             ///< Fade in and out as the burr starts and stops [s].
  double idle_level = 0.15;                       ///< Amplitude of f0 free running, in [0, 1].
  double cutting_level = 0.25;                    ///< Added to f0's amplitude at a removal rate >> half_level_rate.
  double half_level_rate_mm3_per_s = 5.0;         ///< Removal rate at half the added level [mm^3/s], > 0.
  double second_harmonic = 0.4;                   ///< Amplitude of 2 f0 relative to f0's, in [0, 1].
  double third_harmonic = 0.15;                   ///< Amplitude of 3 f0 relative to f0's, in [0, 1].
  double whine_level = 0.15;                      ///< Amplitude of the rotation frequency n / 60 relative to f0's, [0, 1].
  double noise_level = 0.1;                       ///< RMS of the cutting noise at a saturating removal rate, >= 0.
  double noise_centre_fraction = 0.5;             ///< Centre of the noise's band, a fraction of f0, > 0.
  double noise_q = 1.5;                           ///< Quality factor of the noise's band-pass, > 0.
  std::uint32_t noise_seed = 0x9e3779b9u;         ///< Seed of the noise (deterministic output), != 0.
};

/// The burr's tone and cutting noise, rendered block by block.
class BurrSound {
 public:
  /// @throws std::invalid_argument naming the field for a constant outside its range (see BurrSoundModel).
  explicit BurrSound(const BurrSoundModel& model = {});

  /// The state to move towards from the next sample on (smoothed: no click). Non-finite or
  /// negative force, hardness or rate count as 0.
  void setState(const BurrState& state) noexcept;

  /// Renders out.size() samples (overwrites out). No allocation, no exception, no lock.
  void render(std::span<float> out) noexcept;
  /// Adds gain times the next out.size() samples to out. No allocation, no exception, no lock.
  void mixInto(std::span<float> out, float gain = 1.0f) noexcept;

  /// The steady speed under `state` on the motor's line [rpm]: n0 (1 - T_load / T_stall), at
  /// least min_speed_fraction n0; 0 when the burr is off.
  double steadySpeed_rpm(const BurrState& state) const noexcept;
  /// The speed now (smoothed) [rpm].
  double speed_rpm() const noexcept { return speed_rpm_; }
  /// The fundamental now, flutes times the revolutions per second [Hz].
  double fundamental_Hz() const noexcept { return speed_rpm_ / 60.0 * model_.flutes; }
  const BurrSoundModel& model() const noexcept { return model_; }

 private:
  float next() noexcept;  // one sample, smoothing and oscillators advanced
  void retuneNoise() noexcept;

  BurrSoundModel model_;
  BurrState target_;
  double target_speed_rpm_ = 0.0;
  double target_tone_ = 0.0;   // f0's amplitude (gate excluded)
  double target_noise_ = 0.0;  // noise RMS (gate excluded)
  // Smoothed values and their per-sample coefficients (1 - exp(-1 / (tau fs)); 1: at once).
  double speed_rpm_ = 0.0, tone_ = 0.0, noise_ = 0.0, gate_ = 0.0;
  double a_speed_ = 1.0, a_level_ = 1.0, a_gate_ = 1.0;
  // Phases in cycles [0, 1): the tooth-passing tone (its harmonics are multiples) and the whine.
  double phase_f0_ = 0.0, phase_rot_ = 0.0;
  // The noise's band-pass (Simper's SVF: coefficients and its two integrator states), retuned
  // every few samples as f0 moves; noise_gain_ scales white noise in [-1, 1] to unit RMS out.
  double svf_a1_ = 0.0, svf_a2_ = 0.0, svf_a3_ = 0.0, svf_k_ = 1.0, ic1_ = 0.0, ic2_ = 0.0, noise_gain_ = 0.0;
  int retune_countdown_ = 0;
  std::uint32_t rng_;
};

}  // namespace vh::audio
