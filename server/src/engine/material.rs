//! Isotropic linear-elastic materials.

/// An isotropic linear-elastic material with its density.
///
/// Valid ranges (checked by the scene loader): `young_modulus > 0` (Pa),
/// `0 ≤ poisson_ratio < 0.5` (dimensionless; 0.5 would be incompressible, where the
/// first Lamé coefficient λ is infinite), `density > 0` (kg/m³).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Young's modulus E, Pa.
    pub young_modulus: f64,
    /// Poisson's ratio ν.
    pub poisson_ratio: f64,
    /// Mass density ρ, kg/m³.
    pub density: f64,
}

impl Material {
    /// The Lamé coefficients `(λ, μ)`:
    /// `λ = E ν / ((1 + ν)(1 − 2ν))`, `μ = E / (2(1 + ν))`.
    pub fn lame(&self) -> (f64, f64) {
        let (e, nu) = (self.young_modulus, self.poisson_ratio);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        (lambda, mu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_coefficients_recover_young_and_poisson() {
        // E = μ(3λ + 2μ)/(λ + μ) and ν = λ / (2(λ + μ)) invert the definition.
        for &(e, nu) in &[(3000.0, 0.3), (4000.0, 0.45), (1e7, 0.49), (1.0, 0.0)] {
            let (l, m) = Material {
                young_modulus: e,
                poisson_ratio: nu,
                density: 1.0,
            }
            .lame();
            assert!((m * (3.0 * l + 2.0 * m) / (l + m) - e).abs() <= 1e-12 * e);
            assert!((l / (2.0 * (l + m)) - nu).abs() <= 1e-12);
        }
    }
}
