#pragma once
// The dry Hertz contact of a rolling elliptic contact in the units of
// RollingConfig: the limit its pressure approaches for large M, and the
// footprint the domain must hold.
namespace ehlsim {

/// An ellipse with semi-axes ax (along X, the rolling) and ay, and its central
/// pressure p0, in the Hertz units of the ball of radius Rx.
struct EllipticHertzContact {
  double ax = 0.0, ay = 0.0, p0 = 0.0;
};

/// Hertz's contact of the gap X^2/2 + D Y^2/2 under the load Int P = 2 pi / 3
/// with the deformation (2/pi^2) Int P / r (D = Rx / Ry > 0): for D = 1 the
/// unit circle with p0 = 1.  Beyond D or 1 / D of about 3e297 the axis ratio
/// stays at 1e-150 (finite, and far outside any domain).
[[nodiscard]] EllipticHertzContact dry_elliptic_hertz(double D);

}  // namespace ehlsim
