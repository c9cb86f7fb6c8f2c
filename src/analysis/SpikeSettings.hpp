#pragma once
// Settings of the pressure-spike analysis (section 3 of Lubrecht & Venner 2022;
// docs/model.md, "Spike analysis").  Values only: defaults, ranges and
// documentation of the `spike.*` keys live once, in the parameter registry
// (config/Parameters).
namespace ehlsim {

enum class SpikeFilter { Butterworth, Gaussian, None };

struct SpikeSettings {
  /// Moving average over this many consecutive points of the R-sorted P(R):
  /// the paper's "moving 20 point average".
  int smoothing_points = 20;
  /// ... but over at most this width in R, in mesh sizes.  Near the centre the
  /// points are sparse (20 of them span 3.7 meshes at R = 0.04 on 257^2); a
  /// moving average of width w passes the cut-off wavelength lc with the
  /// factor sinc(pi w / lc), 0.95 for w = h/2 and lc = 3h, so the average
  /// does not blur what the filter is meant to keep.  20 points span more
  /// than h/2 only within R < 80 h / pi (25 meshes) of the centre.
  double max_window_meshes = 0.5;
  /// The zero-phase low-pass filter applied after the moving average.
  SpikeFilter filter = SpikeFilter::Butterworth;
  /// Cut-off wavelength of the filter in mesh sizes h: the wavelength passed
  /// with half its amplitude.  Two meshes is the shortest wave the grid can
  /// represent (its Nyquist wavelength); 3 keeps the position of the spike (2-4
  /// meshes wide on 257^2) and removes the direction-dependent discretization
  /// noise (docs/model.md, section 10).
  double cutoff_meshes = 3.0;
  /// Spacing of the uniform R grid the filter works on, in mesh sizes.  1/16
  /// or 1/4 move R_s by at most 0.010 and 0.023 of a mesh (the default case's
  /// snapshots on 257^2 and 513^2, `ehlsim spike RUN_DIR --set
  /// spike.resample_meshes=...`), far below a mesh.
  double resample_meshes = 0.125;
  /// A local maximum counts as the spike only if it is at least this fraction
  /// of the largest filtered pressure (excludes ripples of the low-pressure
  /// squeeze film outside the contact)...  The weakest spike of the default
  /// case's snapshots (T = 2.578, in the contact) is about half of it: 0.5
  /// loses it on 257^2 (not on 513^2), 0.1 finds the same spikes as 0.25.
  double min_height = 0.25;
  /// ... and rises at least this fraction of the largest filtered pressure
  /// above the lowest point between it and the next higher point inward (or
  /// the centre): its inward prominence (excludes wiggles on the flank of the
  /// central pressure dome).  0.05 loses the spike at T = 2.578 on 257^2 and
  /// 513^2, 0.001 finds the same spikes as 0.01.
  double min_prominence = 0.01;
  /// A profile whose largest value is below this (in units of the Hertz
  /// pressure) has no spike: in the last steps before lift-off the pressure
  /// vanishes (7.5e-8 at most in the last step with pressure of M = 20 on
  /// 1025^2), and the relative rules above would find a spike in what is
  /// left of it (a height of 3.4e-10 there, at R = 0.29: docs/performance.md).
  double min_pressure = 0.01;
};

}  // namespace ehlsim
