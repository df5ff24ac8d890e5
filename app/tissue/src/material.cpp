#include "vh/tissue/material.h"

#include <cmath>
#include <stdexcept>

namespace vh::tissue {

double Material::lambda_Pa() const noexcept {
  return youngs_modulus_Pa * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio));
}

double Material::mu_Pa() const noexcept { return youngs_modulus_Pa / (2.0 * (1.0 + poisson_ratio)); }

double Material::contactModulus_Pa() const noexcept { return youngs_modulus_Pa / (1.0 - poisson_ratio * poisson_ratio); }

double Material::pWaveModulus_Pa() const noexcept { return lambda_Pa() + 2.0 * mu_Pa(); }

void Material::validate() const {
  const auto demand = [&](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument("material '" + name + "': " + what);
  };
  demand(std::isfinite(youngs_modulus_Pa) && youngs_modulus_Pa > 0.0, "Young's modulus must be finite and > 0 Pa");
  demand(std::isfinite(poisson_ratio) && poisson_ratio > -1.0 && poisson_ratio < 0.5,
         "Poisson's ratio must lie in (-1, 0.5)");
  demand(std::isfinite(density_kg_per_m3) && density_kg_per_m3 > 0.0, "density must be finite and > 0 kg/m^3");
  demand(std::isfinite(damping_mass_per_s) && damping_mass_per_s >= 0.0, "mass damping must be finite and >= 0 1/s");
  demand(std::isfinite(damping_stiffness_s) && damping_stiffness_s >= 0.0,
         "stiffness damping must be finite and >= 0 s");
}

namespace {

Material preset(const char* name, double E_kPa, double nu, double rho, const char* source) {
  Material m;
  m.name = name;
  m.youngs_modulus_Pa = E_kPa * 1e3;
  m.poisson_ratio = nu;
  m.density_kg_per_m3 = rho;
  m.damping_mass_per_s = 0.0;
  m.damping_stiffness_s = 0.01;
  m.source = source;
  return m;
}

}  // namespace

const std::vector<Material>& materialPresets() {
  static const std::vector<Material> presets = {
      preset("liver", 5.5, 0.45, 1060.0,
             "Roulot et al. 2008, J Hepatol 48:606-613: transient elastography of 429 healthy subjects, "
             "mean 5.5 kPa"),
      preset("muscle", 11.2, 0.45, 1050.0,
             "Knight et al. 2022, IEEE TUFFC 69(3):1045-1057: relaxed vastus lateralis, shear moduli 5.77 "
             "(along) and 1.93 kPa (across the fibres); E = 2 (1 + nu) times their mean"),
      preset("fat", 3.25, 0.45, 920.0,
             "Samani, Zubovits and Plewes 2007, Phys Med Biol 52:1565-1576: normal breast fat, 3.25 kPa"),
      preset("fibroglandular", 3.24, 0.45, 1040.0,
             "Samani, Zubovits and Plewes 2007, Phys Med Biol 52:1565-1576: normal fibroglandular breast "
             "tissue, 3.24 kPa"),
      preset("tumour", 19.99, 0.45, 1050.0,
             "Samani, Zubovits and Plewes 2007, Phys Med Biol 52:1565-1576: intermediate-grade invasive ductal "
             "carcinoma, 19.99 kPa (about 6 times the fat around it)"),
      preset("skin", 35.0, 0.45, 1100.0,
             "Pailler-Mattei, Bec and Zahouani 2008, Med Eng Phys 30:599-606: in vivo indentation of the "
             "forearm, two-layer model, dermis about 35 kPa"),
      preset("brain grey matter", 1.389, 0.45, 1040.0,
             "Budday et al. 2015, J Mech Behav Biomed Mater 46:318-330: indentation of bovine grey matter, "
             "1.389 kPa"),
      preset("brain white matter", 1.895, 0.45, 1040.0,
             "Budday et al. 2015, J Mech Behav Biomed Mater 46:318-330: indentation of bovine white matter, "
             "1.895 kPa"),
      preset("gel", 10.0, 0.45, 1000.0, "the built-in test volume's gel (a soft agar-like phantom)"),
      preset("gel inclusion", 40.0, 0.45, 1000.0, "the built-in test volume's inclusion, 4 times the gel"),
  };
  return presets;
}

const Material& materialPreset(std::string_view name) {
  std::string names;
  for (const Material& m : materialPresets()) {
    if (m.name == name) return m;
    names += (names.empty() ? "" : ", ") + m.name;
  }
  throw std::invalid_argument("no material preset named '" + std::string(name) + "' (presets: " + names + ")");
}

}  // namespace vh::tissue
