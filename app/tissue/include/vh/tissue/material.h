#pragma once
/// @file
/// Linear isotropic elastic materials of soft tissue, with mass and Rayleigh damping, and
/// presets from published measurements. SI units throughout (Pa, kg/m^3, 1/s, s).
#include <string>
#include <string_view>
#include <vector>

namespace vh::tissue {

/// One tissue's material: linear, isotropic, small-strain elasticity (Hooke's law in Lame form)
/// with a lumped mass and Rayleigh damping C = alpha M + beta K.
struct Material {
  std::string name = "tissue";
  double youngs_modulus_Pa = 5.0e3;   ///< E [Pa] (> 0).
  double poisson_ratio = 0.45;        ///< nu, in (-1, 0.5); soft tissue is nearly incompressible (0.45-0.49).
  double density_kg_per_m3 = 1050.0;  ///< rho [kg/m^3] (> 0).
  double damping_mass_per_s = 0.0;    ///< Rayleigh alpha [1/s] (>= 0): C's part proportional to M.
  double damping_stiffness_s = 0.01;  ///< Rayleigh beta [s] (>= 0): C's part proportional to K.
  std::string source;                 ///< Where E comes from (a citation), for the panel and the docs.

  /// First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) [Pa].
  double lambda_Pa() const noexcept;
  /// Shear modulus mu = E / (2 (1 + nu)) [Pa].
  double mu_Pa() const noexcept;
  /// Plane-strain modulus E* = E / (1 - nu^2) [Pa] (Hertz contact against a rigid body).
  double contactModulus_Pa() const noexcept;
  /// P-wave modulus lambda + 2 mu [Pa]: the stiffest of the material's moduli, which sets the
  /// fastest wave speed sqrt((lambda + 2 mu) / rho) of an explicit step's stability limit.
  double pWaveModulus_Pa() const noexcept;

  /// @throws std::invalid_argument naming the field when a value is out of its range or not finite.
  void validate() const;
};

/// Presets from published measurements (each carries its `source`): liver, muscle, fat, skin,
/// breast tumour (several times stiffer than the fat it sits in), brain grey and white matter,
/// and a gel with an inclusion for the test volume. Poisson's ratio 0.45 unless the source says
/// otherwise; density from the same or ICRP tables.
const std::vector<Material>& materialPresets();

/// The preset named `name` (case-sensitive, as in materialPresets()).
/// @throws std::invalid_argument listing the preset names when there is none of that name.
const Material& materialPreset(std::string_view name);

}  // namespace vh::tissue
