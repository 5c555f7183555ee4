//! The fits of one plume: the paper's method, the prior's latent fit and
//! refinement, and the oracle's starts; each writes its rows.

use super::plumes::{measured_region, Row, Which, PRIOR_BLUR};
use super::Setup;
use dualphoton::error::{Error, Result};
use dualphoton::eval::density::{density_metrics, DensityMetrics};
use dualphoton::eval::metrics::rel_rmse;
use dualphoton::image::Image;
use dualphoton::io::npy;
use dualphoton::prior::train::fit_latent;
use dualphoton::prior::Prior;
use dualphoton::recon::hull::{visual_hull, HullSettings};
use dualphoton::recon::methods::Method;
use dualphoton::recon::problem::Problem;
use dualphoton::recon::reconstruct::{prior_model, reconstruct, ReconstructSettings};
use dualphoton::recon::refine::{refine, refine_density};
use dualphoton::render::render_photon;
use dualphoton::scene::rig;
use dualphoton::volume::blur::gaussian_blur;
use dualphoton::volume::Grid;
use std::time::Instant;

/// One plume's problem and where its rows go.
pub struct Plume<'a> {
    pub which: Which,
    pub problem: &'a Problem<'a>,
    pub setup: &'a Setup,
    pub rows_dir: &'a std::path::Path,
    pub cache: &'a std::path::Path,
}

impl Plume<'_> {
    /// The measures of `density` over `region` and of the held-out camera in `images`.
    fn measure(&self, density: &Grid<f64>, region: &[bool], images: &[Image]) -> (DensityMetrics, f64) {
        let truth = self.problem.truth.expect("the evaluation knows every truth");
        let held = rel_rmse(&images[rig::HELD_OUT_CAMERA].data, &self.problem.held_out[0].data)
            .expect("a plume and its images are never all zero");
        (density_metrics(density, truth, region).expect("a plume and its images are never all zero"), held)
    }

    /// Writes `row` and caches `density` as `method`'s.
    fn save(&self, method: &str, density: &Grid<f64>, row: &Row) -> Result<()> {
        let text = serde_json::to_string_pretty(row).map_err(|e| Error(e.to_string()))?;
        std::fs::write(self.rows_dir.join(format!("{}_{method}.json", self.which.name())), text)?;
        let path = self.cache.join(format!("{}_{method}.npy", self.which.name()));
        npy::write_f32(&path, &[density.len()], &density.data)
    }

    /// The final renders of `density`, as a reconstruction with `settings` makes them.
    fn final_render(&self, density: &Grid<f64>, settings: &ReconstructSettings) -> Vec<Image> {
        let mut s = self.problem.scene.clone();
        s.density = density.clone();
        s.render.seed = settings.final_seed();
        render_photon(&s).images
    }

    /// The default hull (the region every row is measured over).
    fn default_hull(&self) -> Vec<bool> {
        let (scene, targets) = (self.problem.scene, self.problem.targets);
        let d = HullSettings::default();
        visual_hull(&scene.density, &scene.cameras[..targets.len()], targets, d.threshold, d.dilate)
    }

    /// `method`'s reconstruction settings (seeded by the plume).
    fn settings(&self, method: &Method) -> ReconstructSettings {
        let scene = self.problem.scene;
        let method = method.clone().seeded(self.which.seed());
        let mut s = ReconstructSettings::new(method, scene.render.photons, scene.render.spp);
        s.hull = self.setup.hull;
        s
    }

    fn label(&self, method: &str) -> String {
        format!("{} {method}", self.which.name())
    }

    /// The paper's method.
    pub fn paper(&self) -> Result<()> {
        let t0 = Instant::now();
        let label = self.label("paper");
        let r = reconstruct(self.problem, &self.settings(&self.setup.paper), &mut |p| eprint!("\r{label}: {p}   "))?;
        eprintln!();
        let (region, fit_hull) = measured_region(&self.default_hull(), &r.model.mask, self.problem.truth.unwrap());
        let (m, held) = self.measure(&r.estimated, &region, &r.final_images);
        let row = Row::new(self.which, "paper", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), r.log.len());
        self.save("paper", &r.estimated, &row)
    }

    /// The prior's latent fit (row `prior`), then its refinement (row `prior_refine`).
    pub fn prior(&self, prior: &Prior) -> Result<()> {
        let t0 = Instant::now();
        let label = self.label("prior");
        let mut settings = self.settings(&self.setup.prior);
        settings.prior = Some(prior.clone());
        // The refinement runs below, after the row of the latent fit.
        let refinement = settings.refine.clone();
        settings.refine.updates = 0;
        let r = reconstruct(self.problem, &settings, &mut |p| eprint!("\r{label}: {p}   "))?;
        eprintln!();
        let (region, fit_hull) = measured_region(&self.default_hull(), &r.model.mask, self.problem.truth.unwrap());
        let updates = r.log.len();
        let (m, held) = self.measure(&r.estimated, &region, &r.final_images);
        let row = Row::new(self.which, "prior", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), updates);
        self.save("prior", &r.estimated, &row)?;
        if refinement.updates == 0 {
            return Ok(());
        }
        let refined = refine(self.problem, &r.model, &refinement, updates, &mut |row| {
            eprint!("\r{label} refine: update {} ({:.0} s)   ", row.iteration + 1 - updates, row.wall_s)
        })?;
        eprintln!();
        let (m, held) = self.measure(&refined, &region, &self.final_render(&refined, &settings));
        let total = updates + refinement.updates;
        let row = Row::new(self.which, "prior_refine", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), total);
        self.save("prior_refine", &refined, &row)
    }

    /// The oracle's starts: the truth measured only, then the blurred truth
    /// and the latent fitted to it, each as it is and after the prior's refinement.
    pub fn oracle(&self, prior: &Prior) -> Result<()> {
        let (scene, truth) = (self.problem.scene, self.problem.truth.unwrap());
        let settings = self.settings(&self.setup.prior);
        let mut decoded = prior_model(scene, self.problem.targets, prior, self.setup.hull)?;
        let mask = decoded.mask.clone();
        let (region, fit_hull) = measured_region(&self.default_hull(), &mask, truth);
        let blurred = gaussian_blur(truth, PRIOR_BLUR);
        // As train_prior's validation fits: 200 Adam steps of 0.05, its latent penalty.
        (decoded.z, _) = fit_latent(&prior.decoder, &prior.w, &blurred.data, &decoded.z, 200, 0.05, 1e-4);
        let mut in_hull = blurred;
        in_hull.data.iter_mut().zip(&mask).for_each(|(v, &m)| *v = if m { *v } else { 0.0 });
        let first = settings.train.iterations;
        // The truth itself, measured only: the floor of the held-out camera's error (render noise).
        let t0 = Instant::now();
        let (m, held) = self.measure(truth, &region, &self.final_render(truth, &settings));
        let row = Row::new(self.which, "oracle_exact", &m, &fit_hull, held, t0.elapsed().as_secs_f64(), 0);
        self.save("oracle_exact", truth, &row)?;
        for (name, start) in [("oracle_truth", in_hull), ("oracle_latent", decoded.density(&scene.density))] {
            let t0 = Instant::now();
            let (m, held) = self.measure(&start, &region, &self.final_render(&start, &settings));
            self.save(name, &start, &Row::new(self.which, name, &m, &fit_hull, held, t0.elapsed().as_secs_f64(), 0))?;
            let label = self.label(name);
            let refined = refine_density(self.problem, &start, &mask, &settings.refine, first, &mut |row| {
                eprint!("\r{label} refine: update {} ({:.0} s)   ", row.iteration + 1 - first, row.wall_s)
            })?;
            eprintln!();
            let (m, held) = self.measure(&refined, &region, &self.final_render(&refined, &settings));
            let name = format!("{name}_refine");
            let updates = settings.refine.updates;
            let row = Row::new(self.which, &name, &m, &fit_hull, held, t0.elapsed().as_secs_f64(), updates);
            self.save(&name, &refined, &row)?;
        }
        Ok(())
    }
}
