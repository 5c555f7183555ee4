//! The image models' stage: every frame fitted on the training cameras under
//! each model, the held-out camera rendered at the capture's resolution and
//! scored. Rows are appended to `fits.csv` as they finish, and a rerun
//! skips the (frame, model) pairs already there, so a long run resumes.
//! The figure frames' panels go to `views/` as their fits finish.

use crate::figures::{self, figure_frames};
use dualphoton::capture::expected_view;
use dualphoton::capture::fit::training_rmse;
use dualphoton::capture::frame::{self, fit_frame, Roles};
use dualphoton::capture::observe::temporal_noise;
use dualphoton::capture::protocol::{Protocol, ORACLE_FINEST_STEPS, ORACLE_MAGNIFICATIONS, ORACLE_SHIFT_PX};
use dualphoton::capture::reuse;
use dualphoton::capture::rig::Rig;
use dualphoton::capture::settings::{FitSettings, ImageModel};
use dualphoton::capture::Capture;
use dualphoton::error::Result;
use dualphoton::eval::metrics::show_score;
use dualphoton::io::manifest::{each_once, git_revision, unrecorded};
use dualphoton::io::plot::{line_chart, Axes, Series};
use dualphoton::io::rows::{fmt, markdown_table, read_rows, write_rows};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One line of fits.csv.
#[derive(Serialize, Deserialize, Clone, Default)]
pub struct FitResult {
    pub frame: usize,
    pub model: String,
    #[serde(serialize_with = "fmt::opt_f4")]
    pub psnr_db: Option<f64>,
    #[serde(serialize_with = "fmt::opt_f4")]
    pub rel_rmse: Option<f64>,
    /// Root mean squared error over the training cameras' pixels at the
    /// working resolution (code value / 255), at the fit's last update.
    #[serde(serialize_with = "fmt::f6")]
    pub train_rmse: f64,
    /// The training photographs' own noise, on the same pixels and scale
    /// (`capture::observe::temporal_noise`; an upper bound).
    #[serde(serialize_with = "fmt::opt_f6")]
    pub train_noise: Option<f64>,
    #[serde(serialize_with = "fmt::f1")]
    pub fit_s: f64,
    #[serde(serialize_with = "fmt::f1")]
    pub render_s: f64,
    /// The fitted lights' intensities (`;`-separated; a disc's points in turn).
    pub lights: String,
    #[serde(serialize_with = "fmt::e6")]
    pub emission: f64,
    /// The lights' share of the training images' light, the rest the
    /// emission's (lit models).
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub light_share: Option<f64>,
    /// Per training camera (`;`-separated, in the training cameras' order):
    /// its fitted gain, its black level (code values, of 255; 0 unless
    /// fitted), how far its principal point moved (full-resolution
    /// pixels, right then down, `x/y`), the factor its focal lengths
    /// were scaled by and the angle it was turned by (degrees).
    #[serde(default)]
    pub gains: String,
    #[serde(default)]
    pub black_levels_codes: String,
    #[serde(default)]
    pub offsets_px: String,
    #[serde(default)]
    pub zooms: String,
    #[serde(default)]
    pub rolls_deg: String,
    /// Diagnostics that only the held-out photograph gives, never used to
    /// choose anything (`capture::protocol::Oracle`): the least-squares gain
    /// of the held-out view onto its photograph and the PSNR with it, and
    /// the PSNR with the best whole-pixel shift of the protocol's view
    /// (`x/y`, half-resolution pixels).
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub oracle_gain: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_oracle_gain_db: Option<f64>,
    #[serde(default)]
    pub oracle_shift_px: String,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_oracle_shift_db: Option<f64>,
    /// The same with the held-out camera aligned as the training cameras
    /// are (`capture::protocol::Aligned`): the best magnification about its
    /// principal point, the best shift after it (`x/y`) and the PSNR and
    /// relative RMSE with both.
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub oracle_magnification: Option<f64>,
    #[serde(default)]
    pub oracle_aligned_shift_px: String,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_oracle_aligned_db: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub rel_rmse_oracle_aligned: Option<f64>,
    /// What a reconstruction exact to the smoke would score through the
    /// held-out camera, off by the error the alignment above found
    /// (`capture::protocol::ExactSmoke`): its photograph moved back by that
    /// magnification and shift, PSNR and relative RMSE; and by the
    /// magnification alone.
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_exact_smoke_db: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub rel_rmse_exact_smoke: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_exact_smoke_magnification_db: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub rel_rmse_exact_smoke_magnification: Option<f64>,
    /// The held-out view averaged over the calibration error the training
    /// cameras show (`capture::expected_view`): its PSNR and relative RMSE.
    /// Needs nothing of the held-out photograph.
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub psnr_expected_db: Option<f64>,
    #[serde(default, serialize_with = "fmt::opt_f4")]
    pub rel_rmse_expected: Option<f64>,
    /// The revision of the binary that fitted this row (`git_revision`;
    /// `unrecorded` in a row written before it was recorded): a resumed
    /// run's rows may come from several.
    #[serde(default = "unrecorded")]
    pub revision: String,
}

/// The revisions that fitted `rows`, each once, in the order they first appear.
pub fn revisions(rows: &[FitResult]) -> Vec<String> {
    each_once(rows.iter().map(|r| r.revision.as_str())).into_iter().map(String::from).collect()
}

/// The rig, fitted under the model `settings` chose for it, in words and a
/// table, for summary.md.
pub fn rig_note(rig: &Rig, settings: &FitSettings) -> String {
    let frames: Vec<String> = rig.frames.iter().map(|f| f.to_string()).collect();
    let mut md = format!(
        "\nThe training cameras were aligned once for every frame, on frames {} under \
         {} ({:.0} s, once per run): per camera how far its principal point moved \
         (pixels of the capture, right and down) and the factor its focal lengths were scaled by.",
        frames.join(", "),
        rig.model.unwrap_or(settings.rig_model).name(),
        rig.seconds
    );
    if let (Some(share), Some(bound)) = (rig.lit_share, settings.rig_lit_share) {
        md += &format!(
            " The model follows the rule fixed in the settings: fitted under multiple scattering, \
             frame {} gave the lights {:.1} % of its training images' light, {} the bound of {:.1} %.",
            rig.frames[0],
            100.0 * share,
            if share > bound { "above" } else { "not above" },
            100.0 * bound
        );
    }
    // The turn about the optical axis where it was fitted (`roll`), as a column of its own.
    let turned = rig.cameras.iter().any(|c| c.roll_deg != 0.0);
    if turned {
        md +=
            " Each camera was also turned about its optical axis (degrees, from the image's right towards its bottom).";
    }
    md += "\n\n";
    let rows = rig.cameras.iter().map(|c| {
        let mut row = vec![
            c.name.clone(),
            format!("{:.1}", c.offset_px[0]),
            format!("{:.1}", c.offset_px[1]),
            format!("{:.4}", c.zoom),
        ];
        if turned {
            row.push(format!("{:.3}", c.roll_deg));
        }
        row
    });
    let mut head = vec!["camera", "right (px)", "down (px)", "focal length factor"];
    if turned {
        head.push("turn (degrees)");
    }
    md += &markdown_table(&head, rows);
    md
}

/// How many frames' photographs are read at once: a full-resolution
/// 1080x1920 photograph takes 16.6 MB, so a clip is never read whole.
pub const FRAMES_AT_ONCE: usize = 8;

/// Fits every frame of `frames` under every model of `models`, scoring the
/// one held-out camera of `roles` against its photograph there.
pub fn run(
    capture: &Capture,
    roles: &Roles,
    frames: &[usize],
    models: &[ImageModel],
    base: &FitSettings,
    csv: &Path,
    views: &Path,
) -> Result<(Vec<FitResult>, Option<Rig>)> {
    let mut rows: Vec<FitResult> = if csv.exists() { read_rows(csv)? } else { Vec::new() };
    let done = |rows: &[FitResult], frame: usize, model: ImageModel| {
        rows.iter().any(|r| r.frame == frame && r.model == model.name())
    };
    let todo: Vec<usize> = frames.iter().copied().filter(|&f| models.iter().any(|&m| !done(&rows, f, m))).collect();
    let kept: usize = frames.iter().map(|&f| models.iter().filter(|&&m| done(&rows, f, m)).count()).sum();
    if kept > 0 {
        eprintln!(
            "{}: {kept} of {} fits are there already and are kept (a run with the same settings resumes; \
             --out another folder fits every frame afresh)",
            csv.display(),
            frames.len() * models.len()
        );
    }
    let rig = reuse::rig(capture, roles, base, &csv.with_file_name("rig.json"))?;
    let shown = figure_frames(frames);
    // A few frames at a time: a frame's photographs are read at full
    // resolution before they are downsampled.
    for frames_now in todo.chunks(FRAMES_AT_ONCE) {
        for images in frame::read(capture, roles, frames_now, base)? {
            let frame = images.frame;
            let noise = temporal_noise(capture, &roles.training, frame, base)?;
            let pending: Vec<ImageModel> = models.iter().copied().filter(|&m| !done(&rows, frame, m)).collect();
            for model in pending {
                let settings = FitSettings { model, ..base.clone() };
                let result = fit_frame(capture, roles, &images, &settings, rig.as_ref(), &mut |row| {
                    if row.update % 20 == 0 {
                        eprintln!(
                            "  frame {frame} {}: stage {} update {} image rmse {:.5} ({:.0} s)",
                            model.name(),
                            row.level,
                            row.update,
                            row.image_mse.sqrt(),
                            row.seconds
                        );
                    }
                })?;
                let held = &result.held_out[0];
                let fitted = &result.fit;
                let camera = &capture.views[held.view].camera;
                let expected = expected_view::score(camera, &held.prediction, fitted, &images.held_out[0]);
                if shown.contains(&frame) {
                    figures::keep(views, frame, model.name(), &held.prediction, &fitted.scene.density)?;
                }
                let row = FitResult {
                    frame,
                    model: model.name().into(),
                    psnr_db: held.score.psnr,
                    rel_rmse: held.score.rel_rmse,
                    train_rmse: training_rmse(fitted, &images.training.images[0]),
                    train_noise: noise,
                    fit_s: fitted.seconds,
                    render_s: held.render_s,
                    lights: joined(fitted.scene.lights.iter().map(|l| format!("{:.4e}", l.intensity))),
                    emission: fitted.scene.medium.emission,
                    light_share: fitted.light_share,
                    gains: joined(fitted.gains.iter().map(|g| format!("{g:.4}"))),
                    black_levels_codes: joined(fitted.black_levels.iter().map(|b| format!("{:.2}", 255.0 * b))),
                    offsets_px: joined(fitted.offsets_px().iter().map(|o| format!("{:.1}/{:.1}", o[0], o[1]))),
                    zooms: joined(fitted.zooms.iter().map(|z| format!("{z:.4}"))),
                    rolls_deg: joined(fitted.rolls.iter().map(|r| format!("{:.3}", r.to_degrees()))),
                    oracle_gain: Some(held.oracle.gain),
                    psnr_oracle_gain_db: held.oracle.with_gain.psnr,
                    oracle_shift_px: format!("{}/{}", held.oracle.shift[0], held.oracle.shift[1]),
                    psnr_oracle_shift_db: held.oracle.with_shift.psnr,
                    oracle_magnification: Some(held.aligned.magnification),
                    oracle_aligned_shift_px: format!("{}/{}", held.aligned.shift[0], held.aligned.shift[1]),
                    psnr_oracle_aligned_db: held.aligned.score.psnr,
                    rel_rmse_oracle_aligned: held.aligned.score.rel_rmse,
                    psnr_exact_smoke_db: held.exact.through_aligned.psnr,
                    rel_rmse_exact_smoke: held.exact.through_aligned.rel_rmse,
                    psnr_exact_smoke_magnification_db: held.exact.through_magnification.psnr,
                    rel_rmse_exact_smoke_magnification: held.exact.through_magnification.rel_rmse,
                    psnr_expected_db: expected.psnr,
                    rel_rmse_expected: expected.rel_rmse,
                    revision: git_revision(),
                };
                eprintln!(
                    "frame {frame} {}: held-out PSNR {}, relative RMSE {} (expected view {}, {}), fit {:.0} s, \
                 render {:.0} s",
                    model.name(),
                    show_score(held.score.psnr, 1.0, 2, " dB"),
                    show_score(held.score.rel_rmse, 100.0, 1, " %"),
                    show_score(expected.psnr, 1.0, 2, " dB"),
                    show_score(expected.rel_rmse, 100.0, 1, " %"),
                    row.fit_s,
                    row.render_s
                );
                rows.push(row);
                write_rows(csv, &rows)?;
            }
        }
    }
    Ok((rows, rig))
}

/// `items` separated by `;` (one CSV field).
fn joined(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(";")
}

/// The models' table (Markdown): per model the mean over the frames of
/// the held-out PSNR and relative RMSE, the training RMSE and the seconds
/// per frame, and how many frames; then the lit models against
/// emission-absorption frame by frame.
pub fn table(rows: &[FitResult], models: &[ImageModel]) -> String {
    // The mean of the frames that define a value, scaled; empty where none does.
    let cell = |v: Vec<f64>, scale: f64, decimals: usize| match v.len() {
        0 => String::new(),
        n => format!("{:.*}", decimals, scale * (v.iter().sum::<f64>() / n as f64)),
    };
    let lines = models.iter().map(|m| {
        let mine: Vec<&FitResult> = rows.iter().filter(|r| r.model == m.name()).collect();
        vec![
            m.name().to_string(),
            cell(mine.iter().filter_map(|r| r.psnr_db).collect(), 1.0, 2),
            cell(mine.iter().filter_map(|r| r.rel_rmse).collect(), 100.0, 1),
            cell(mine.iter().map(|r| r.train_rmse).collect(), 255.0, 2),
            cell(mine.iter().filter_map(|r| r.train_noise).collect(), 255.0, 2),
            cell(mine.iter().filter_map(|r| r.light_share).collect(), 100.0, 0),
            cell(mine.iter().map(|r| r.fit_s + r.render_s).collect(), 1.0, 0),
            mine.len().to_string(),
        ]
    });
    let mut md = markdown_table(
        &[
            "image model",
            "held-out PSNR (dB)",
            "held-out relative RMSE (%)",
            "training RMSE (code values)",
            "training photographs' noise (code values)",
            "the lights' share of the training images (%)",
            "seconds per frame",
            "frames",
        ],
        lines,
    );
    let ea = ImageModel::EmissionAbsorption.name();
    for m in models.iter().filter(|m| m.name() != ea) {
        let diffs: Vec<f64> = rows
            .iter()
            .filter(|r| r.model == m.name())
            .filter_map(|r| {
                let e = rows.iter().find(|e| e.frame == r.frame && e.model == ea)?;
                Some(r.psnr_db? - e.psnr_db?)
            })
            .collect();
        if !diffs.is_empty() {
            let wins = diffs.iter().filter(|&&d| d > 0.0).count();
            md += &format!(
                "\n{} against {ea}: {:+.2} dB mean held-out PSNR, ahead on {wins} of {} frames.\n",
                m.name(),
                diffs.iter().sum::<f64>() / diffs.len() as f64,
                diffs.len()
            );
        }
    }
    md + &oracle_table(rows, models) + &exact_smoke_table(rows, models)
}

/// A column of fits.csv, its scale and its decimals in a table.
type MeanColumn = (fn(&FitResult) -> Option<f64>, f64, usize);

/// One line per model: its name, then each column's mean over the model's
/// rows, scaled and rounded. A model with no rows, or a row that lacks a
/// column (written before it existed), has no line.
fn mean_lines(rows: &[FitResult], models: &[ImageModel], columns: &[MeanColumn]) -> Vec<Vec<String>> {
    models
        .iter()
        .filter_map(|m| {
            let mine: Vec<&FitResult> = rows.iter().filter(|r| r.model == m.name()).collect();
            let cells = columns.iter().map(|&(column, scale, decimals)| {
                let v: Vec<f64> = mine.iter().filter_map(|r| column(r)).collect();
                (v.len() == mine.len() && !v.is_empty())
                    .then(|| format!("{:.*}", decimals, scale * v.iter().sum::<f64>() / v.len() as f64))
            });
            std::iter::once(Some(m.name().to_string())).chain(cells).collect()
        })
        .collect()
}

/// What only the held-out photograph could have fixed (Markdown): per model
/// the mean held-out PSNR as scored, with the least-squares gain onto the
/// photograph, and with the best whole-pixel shift. A diagnostic of where
/// the error lies, never used to choose anything.
fn oracle_table(rows: &[FitResult], models: &[ImageModel]) -> String {
    let lines = mean_lines(
        rows,
        models,
        &[
            (|r| r.psnr_db, 1.0, 2),
            (|r| r.oracle_gain, 1.0, 3),
            (|r| r.psnr_oracle_gain_db, 1.0, 2),
            (|r| r.psnr_oracle_shift_db, 1.0, 2),
            (|r| r.oracle_magnification, 1.0, 4),
            (|r| r.psnr_oracle_aligned_db, 1.0, 2),
            (|r| r.rel_rmse_oracle_aligned, 100.0, 1),
        ],
    );
    if lines.is_empty() {
        return String::new();
    }
    format!(
        "\nWhat only the held-out photograph could have fixed (a diagnostic, never used to choose anything): \
         the held-out view scaled by its least-squares gain onto the photograph, or moved by the best \
         whole-pixel shift (at most {ORACLE_SHIFT_PX} pixels of the protocol's view each way), or aligned as \
         the training cameras are (the best magnification about its principal point, {:.2} to {:.2}, and the \
         best shift after it, to {} in magnification and {} of the view's pixel). Mean over frames:\n\n",
        ORACLE_MAGNIFICATIONS[0],
        ORACLE_MAGNIFICATIONS[ORACLE_MAGNIFICATIONS.len() - 1],
        ORACLE_FINEST_STEPS[0],
        ORACLE_FINEST_STEPS[1]
    ) + &markdown_table(
        &[
            "image model",
            "held-out PSNR (dB)",
            "least-squares gain",
            "PSNR with that gain (dB)",
            "PSNR with the best shift (dB)",
            "best magnification",
            "PSNR with the best magnification and shift (dB)",
            "relative RMSE with them (%)",
        ],
        lines,
    )
}

/// What the smoke itself would score through the held-out camera, off by
/// the error the aligned oracle found (Markdown): per model the mean held-out
/// PSNR as scored beside that of the photograph moved back by the error, and
/// by its magnification alone. Models whose rows predate these columns are
/// left out.
fn exact_smoke_table(rows: &[FitResult], models: &[ImageModel]) -> String {
    let lines = mean_lines(
        rows,
        models,
        &[
            (|r| r.psnr_db, 1.0, 2),
            (|r| r.rel_rmse, 100.0, 1),
            (|r| r.psnr_exact_smoke_db, 1.0, 2),
            (|r| r.rel_rmse_exact_smoke, 100.0, 1),
            (|r| r.psnr_exact_smoke_magnification_db, 1.0, 2),
            (|r| r.rel_rmse_exact_smoke_magnification, 100.0, 1),
        ],
    );
    if lines.is_empty() {
        return String::new();
    }
    "\nWhat a reconstruction exact to the smoke would score through the held-out camera, were its \
     calibration off by the error found above (a diagnostic, never used to choose anything): the \
     photograph moved back by that magnification and shift, scored against itself; and moved back by the \
     magnification alone, a camera off by that only. Mean over frames:\n\n"
        .to_string()
        + &markdown_table(
            &[
                "image model",
                "held-out PSNR (dB)",
                "held-out relative RMSE (%)",
                "the smoke through the magnification and shift (dB)",
                "relative RMSE (%)",
                "the smoke through the magnification alone (dB)",
                "relative RMSE (%)",
            ],
            lines,
        )
}

/// `psnr_per_frame.svg`: the held-out PSNR of every model per frame.
pub fn plot(
    path: &Path,
    rows: &[FitResult],
    models: &[ImageModel],
    floor: &[(usize, f64)],
    protocol: &Protocol,
) -> Result<()> {
    // In frame order, whatever order the frames were fitted in.
    let in_order = |mut points: Vec<(f64, f64)>| {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points
    };
    let mut series: Vec<Series> = models
        .iter()
        .map(|m| Series {
            name: m.name().into(),
            points: in_order(
                rows.iter()
                    .filter(|r| r.model == m.name())
                    .filter_map(|r| Some((r.frame as f64, r.psnr_db?)))
                    .collect(),
            ),
            markers: true,
        })
        .collect();
    if !floor.is_empty() {
        series.push(Series {
            name: "nearest training view as is".into(),
            points: in_order(floor.iter().map(|&(f, p)| (f as f64, p)).collect()),
            markers: false,
        });
    }
    let title = format!("Held-out camera, {}", protocol.name());
    let axes = Axes { title: &title, x: "frame", y: "PSNR (dB)", log_x: false, log_y: false };
    line_chart(path, &axes, &series)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dualphoton::io::manifest::UNRECORDED;

    #[test]
    fn a_resumed_table_names_each_revision_that_fitted_it_once() {
        let row = |revision: &str| FitResult { revision: revision.into(), ..FitResult::default() };
        let rows =
            [row(UNRECORDED), row("aaaaaaaaaaaa"), row("bbbbbbbbbbbb-dirty"), row("aaaaaaaaaaaa"), row(UNRECORDED)];
        assert_eq!(revisions(&rows), [UNRECORDED, "aaaaaaaaaaaa", "bbbbbbbbbbbb-dirty"]);
    }

    #[test]
    fn rows_written_before_revisions_were_kept_read_as_unrecorded() {
        let path = std::env::temp_dir().join(format!("dualphoton-fits-{}.csv", std::process::id()));
        std::fs::write(
            &path,
            "frame,model,psnr_db,rel_rmse,train_rmse,train_noise,fit_s,render_s,lights,emission\n\
                               0,multiple,36.7591,0.3487,0.005586,0.002594,12.4,0.3,0.0;1.0,7.4e-1\n",
        )
        .unwrap();
        let rows: Vec<FitResult> = read_rows(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(revisions(&rows), [UNRECORDED]);
        assert_eq!((rows[0].frame, rows[0].psnr_db), (0, Some(36.7591)));
    }
}
