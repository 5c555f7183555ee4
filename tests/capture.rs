//! Real captures in: calibrations of both forms, frames from images, `.npy`
//! and videos, and the errors a bad capture gets. The data is made here:
//! tiny images, and a tiny H.264 video when `ffmpeg` is installed (the test
//! that needs it says that it skips when it is not).

mod common;

use common::capture::{looking_at_origin, write_png, write_video};
use common::temp_dir;
use dualphoton::capture::frame::{check, Roles};
use dualphoton::capture::settings::FitSettings;
use dualphoton::capture::{calibration, frames, Frames};
use dualphoton::io::npy;
use dualphoton::math::Vec3;
use serde_json::{json, Value};
use std::path::Path;

#[test]
fn a_transforms_json_reads_folders_of_images_of_every_kind() {
    let dir = temp_dir("capture_transforms");
    for (cam, sixteen) in [("cam_a", false), ("cam_b", true)] {
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        for n in 0..3u16 {
            write_png(&dir.join(cam).join(format!("{n:03}.png")), 6, 4, sixteen, |x, y| {
                10 * n + x as u16 + 6 * y as u16
            });
        }
    }
    std::fs::create_dir_all(dir.join("cam_c")).unwrap();
    for n in 0..3 {
        let data: Vec<f64> = (0..24).map(|i| 0.01 * (i + n) as f64).collect();
        npy::write_f32(&dir.join("cam_c").join(format!("{n}.npy")), &[4, 6], &data).unwrap();
    }
    // nerfstudio's OPENCV lens with its coefficients 0 is a pinhole.
    let calib = json!({
        "camera_angle_x": 0.8, "w": 6, "h": 4, "camera_model": "OPENCV", "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
        "frames": [
            {"file_path": "cam_a", "transform_matrix": looking_at_origin(0.0, 2.0)},
            {"file_path": "cam_b", "transform_matrix": looking_at_origin(2.0, 0.0), "fl_x": 7.0, "cx": 2.5},
            {"file_path": "cam_c", "transform_matrix": looking_at_origin(-2.0, 0.0)},
        ]
    });
    std::fs::write(dir.join("transforms.json"), calib.to_string()).unwrap();
    let capture = calibration::load(&dir.join("transforms.json")).unwrap();
    assert_eq!(capture.views.len(), 3);
    assert_eq!((capture.frame_count(), capture.smoke_box), (3, None));
    assert_eq!(capture.views[1].name, "cam_b");
    // Every camera sees the origin; the one at the top-level angle at the image centre.
    for v in &capture.views {
        assert!(v.camera.project(&Vec3::zeros()).is_some(), "{}", v.name);
    }
    let (x, y) = capture.views[0].camera.project(&Vec3::zeros()).unwrap();
    assert!((x - 3.0).abs() < 1e-9 && (y - 2.0).abs() < 1e-9);
    assert_eq!(capture.views[1].camera.intrinsics(), [7.0, 7.0, 2.5, 2.0]);
    // A `.npy` frame's size from its header: (H, W) is 6 wide, 4 high.
    assert_eq!(frames::image_size(&dir.join("cam_c/0.npy")).unwrap(), (6, 4));

    let a = frames::read(&capture.views[0], &[2, 0]).unwrap();
    assert_eq!(a[0].data[7], (20.0 + 1.0 + 6.0) / 255.0);
    assert_eq!(a[1].data[0], 0.0);
    let b = frames::read(&capture.views[1], &[1]).unwrap();
    assert_eq!(b[0].data[23], (10.0 + 5.0 + 18.0) / 65535.0);
    let c = frames::read(&capture.views[2], &[2]).unwrap();
    assert!((c[0].data[5] - 0.07).abs() < 1e-7);

    let err = frames::read(&capture.views[0], &[3]).unwrap_err().0;
    assert!(err.contains("frame 3 is out of range") && err.contains("0..2"), "{err}");
    // Contradictory choices are refused before any work.
    let roles = Roles::choose(&capture, Some("cam_b"), &[]).unwrap();
    let err = check(&capture, &roles, &[1, 2, 1], &FitSettings::default()).unwrap_err().0;
    assert_eq!(err, "frame 1 is given twice");
    let err = Roles::choose(&capture, Some("cam_b"), &["cam_b".into()]).unwrap_err().0;
    assert!(err.starts_with("--drop: cam_b is the held-out camera"), "{err}");

    // A file_path without an extension (the NeRF synthetic scenes' form) is
    // the image of that name with one; without such an image, an error.
    let bare = |path: &str| {
        let frames = json!([{"file_path": path, "transform_matrix": looking_at_origin(0.0, 2.0)}]);
        std::fs::write(dir.join("bare.json"), json!({"camera_angle_x": 0.8, "frames": frames}).to_string()).unwrap();
        calibration::load(&dir.join("bare.json"))
    };
    let one = bare("./cam_a/001").unwrap();
    assert_eq!((one.views[0].name.as_str(), one.frame_count()), ("001", 1));
    assert_eq!((one.views[0].camera.width, one.views[0].camera.height), (6, 4));
    assert_eq!(frames::read(&one.views[0], &[0]).unwrap()[0].data[7], (10.0 + 1.0 + 6.0) / 255.0);
    assert_eq!(bare("./cam_c/2").unwrap().views[0].frames.count(), 1);
    let err = bare("./cam_a/009").unwrap_err().0;
    assert!(err.contains("cam_a/009 does not exist, with or without .png"), "{err}");

    // An image with alpha (smoke on a transparent background) is composited over black.
    let rgba = dir.join("rgba.png");
    image::ImageBuffer::from_fn(6, 4, |x, _| image::Rgba([200u8, 100, 0, if x == 0 { 255 } else { 51 }]))
        .save(&rgba)
        .unwrap();
    let smoke = frames::read(&bare("rgba").unwrap().views[0], &[0]).unwrap().remove(0);
    assert_eq!(smoke.data[0], 300.0 / (3.0 * 255.0));
    assert!((smoke.data[1] - 0.2 * 300.0 / (3.0 * 255.0)).abs() < 1e-15, "{}", smoke.data[1]);
}

/// Cameras are named by their frames' file or folder, or by its path where
/// two names would be the same, so that each name picks one camera.
#[test]
fn cameras_whose_frames_share_a_name_are_named_by_their_path() {
    let dir = temp_dir("capture_names");
    for cam in ["cam0", "cam1"] {
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        write_png(&dir.join(cam).join("000060.png"), 6, 4, false, |_, _| 0);
    }
    let frame = |file: &str, x: f64| json!({"file_path": file, "transform_matrix": looking_at_origin(x, 2.0)});
    let names = |frames: Vec<Value>| {
        let path = dir.join("transforms.json");
        std::fs::write(&path, json!({"camera_angle_x": 0.8, "frames": frames}).to_string()).unwrap();
        calibration::load(&path).map(|c| c.views.iter().map(|v| v.name.clone()).collect::<Vec<_>>())
    };
    let two = vec![frame("cam0/000060.png", 0.0), frame("cam1/000060.png", 1.0)];
    assert_eq!(names(two).unwrap(), ["cam0/000060", "cam1/000060"]);
    assert_eq!(names(vec![frame("cam0", 0.0), frame("cam1/", 1.0)]).unwrap(), ["cam0", "cam1"]);
    let err = names(vec![frame("cam0", 0.0), frame("cam1", 1.0), frame("cam0/", 2.0)]).unwrap_err().0;
    assert!(err.contains("cameras 0 and 2") && err.contains("named cam0") && !err.contains('\n'), "{err}");
}

/// A `transforms.json` may list each camera once per frame (an entry per
/// image): entries with one pose and lens are one camera, its frames ordered
/// by `time` where given.
#[test]
fn a_transforms_json_listing_each_camera_once_per_frame_is_read_as_its_cameras() {
    let dir = temp_dir("capture_per_image");
    std::fs::create_dir_all(dir.join("all")).unwrap();
    for cam in 0..2u16 {
        std::fs::create_dir_all(dir.join(format!("cam{cam}"))).unwrap();
        for n in 0..3u16 {
            let code = |_: u32, _: u32| 100 * cam + 10 * n;
            write_png(&dir.join(format!("cam{cam}/{n}.png")), 6, 4, false, code);
            write_png(&dir.join(format!("all/c{cam}_{n}.png")), 6, 4, false, code);
        }
    }
    let entry = |cam: u16, n: u16, time: Option<f64>, folder: bool| {
        let file = if folder { format!("cam{cam}/{n}.png") } else { format!("all/c{cam}_{n}.png") };
        let mut e = json!({"file_path": file, "transform_matrix": looking_at_origin(cam as f64, 2.0)});
        if let Some(t) = time {
            e["time"] = json!(t);
        }
        e
    };
    let load = |frames: Vec<Value>| {
        let path = dir.join("transforms.json");
        std::fs::write(&path, json!({"camera_angle_x": 0.8, "frames": frames}).to_string()).unwrap();
        calibration::load(&path)
    };
    // Frame n of camera c is code 100 c + 10 n.
    let codes = |capture: &dualphoton::capture::Capture| -> Vec<Vec<f64>> {
        let view = |v| (0..capture.frame_count()).map(move |n| frames::read(v, &[n]).unwrap()[0].data[0] * 255.0);
        capture.views.iter().map(|v| view(v).map(|c| c.round()).collect()).collect()
    };
    // Interleaved and shuffled, with D-NeRF's times: ordered by time.
    let order = [(1, 2), (0, 1), (1, 0), (0, 2), (0, 0), (1, 1)];
    let timed: Vec<Value> = order.iter().map(|&(c, n)| entry(c, n, Some(0.5 * n as f64), true)).collect();
    let capture = load(timed).unwrap();
    assert_eq!(capture.views.iter().map(|v| v.name.as_str()).collect::<Vec<_>>(), ["cam1", "cam0"]);
    assert_eq!(codes(&capture), [[100.0, 110.0, 120.0], [0.0, 10.0, 20.0]]);
    // Without times, in file order; images of one folder name the cameras by number.
    let untimed: Vec<Value> = (0..3).flat_map(|n| [entry(0, n, None, false), entry(1, n, None, false)]).collect();
    let capture = load(untimed).unwrap();
    assert_eq!(capture.views.iter().map(|v| v.name.as_str()).collect::<Vec<_>>(), ["camera0", "camera1"]);
    assert_eq!(codes(&capture), [[0.0, 10.0, 20.0], [100.0, 110.0, 120.0]]);
    // What cannot be matched frame by frame is a one-line error.
    let refused = |frames: Vec<Value>, says: &str| {
        let err = load(frames).unwrap_err().0;
        assert!(err.contains(says) && !err.contains('\n'), "{err}");
    };
    let missing = vec![entry(0, 0, None, true), entry(0, 1, None, true), entry(1, 0, None, true)];
    refused(missing, "listed for 2 frames, the camera of frames[2] for 1");
    let mut shifted = vec![entry(0, 0, Some(0.0), true), entry(0, 1, Some(1.0), true), entry(1, 0, Some(0.0), true)];
    shifted.push(json!({"file_path": "cam1/1.png", "transform_matrix": looking_at_origin(1.0, 2.0), "time": 2.0}));
    refused(shifted, "frames[3]: time 2 has no match");
    let folder = vec![
        entry(0, 0, None, true),
        entry(0, 1, None, true),
        json!({"file_path": "cam1",
        "transform_matrix": looking_at_origin(1.0, 2.0)}),
    ];
    refused(folder, "frames[2]: names a folder of frames, but this file lists cameras once per frame");
    // One camera moving through the frames (D-NeRF's monocular scenes): every entry its own pose and time.
    let moving: Vec<Value> = (0..2).map(|c| entry(c, c, Some(0.5 * c as f64), true)).collect();
    refused(moving, "the cameras of frames[0] and frames[1] see different times (0 and 0.5)");
    // A fixed camera whose pose moves a little from frame to frame (registered image by image) is told why.
    let mut jittered = vec![entry(0, 0, Some(0.0), true), entry(1, 0, Some(0.0), true), entry(1, 1, Some(0.5), true)];
    jittered.push(json!({"file_path": "cam0/1.png", "transform_matrix": looking_at_origin(0.001, 2.0), "time": 0.5}));
    refused(jittered, "needs the same transform_matrix and intrinsics in each of its entries");
    // Without times nothing tells it from cameras of one instant: it reads so (with a warning).
    let mut untimed = vec![entry(0, 0, None, true), entry(1, 0, None, true)];
    untimed.push(json!({"file_path": "cam0/1.png", "transform_matrix": looking_at_origin(0.001, 2.0)}));
    assert_eq!(load(untimed).unwrap().views.len(), 3);
    // Different cameras at one instant read as before.
    let still: Vec<Value> = (0..2).map(|c| entry(c, 0, Some(0.5), true)).collect();
    assert_eq!(load(still).unwrap().views.len(), 2);
}

#[test]
fn a_bad_capture_is_a_one_line_error_before_any_work() {
    let dir = temp_dir("capture_errors");
    write_png(&dir.join("one.png"), 6, 4, false, |_, _| 0);
    let video = |file: &str, matrix: Value| json!({"file_name": file, "frame_num": 5, "camera_angle_x": 0.5, "camera_hw": [4, 6], "transform_matrix": matrix});
    let cases: Vec<(&str, Value, &str)> = vec![
        (
            "missing video",
            json!({"train_videos": [video("none.mp4", looking_at_origin(0.0, 2.0))]}),
            "none.mp4 does not exist",
        ),
        ("no field", json!({"train_videos": [{"file_name": "one.png"}]}), "train_videos[0].frame_num: missing"),
        (
            "no frames",
            json!({"train_videos": [{"file_name": "one.png", "frame_num": 0, "camera_hw": [4, 6]}]}),
            "frame_num: 0",
        ),
        ("neither form", json!({"cameras": []}), "neither train_videos"),
        (
            "not a rotation",
            json!({"train_videos": [video("one.png", json!([[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2], [0, 0, 0, 1]]))]}),
            "not a rotation",
        ),
        (
            "bad angle",
            json!({"frames": [{"file_path": "one.png", "camera_angle_x": 4.0, "transform_matrix": looking_at_origin(0.0, 2.0)}]}),
            "(0, pi)",
        ),
        (
            "no intrinsics",
            json!({"frames": [{"file_path": "one.png", "transform_matrix": looking_at_origin(0.0, 2.0)}]}),
            "no intrinsics",
        ),
        (
            "a fisheye",
            json!({"camera_model": "OPENCV_FISHEYE", "camera_angle_x": 0.5,
                "frames": [{"file_path": "one.png", "transform_matrix": looking_at_origin(0.0, 2.0)}]}),
            "camera_model OPENCV_FISHEYE: dualphoton models pinhole cameras",
        ),
        (
            "a distorted lens",
            json!({"camera_model": "OPENCV", "camera_angle_x": 0.5, "k1": 0.0,
                "frames": [{"file_path": "one.png", "transform_matrix": looking_at_origin(0.0, 2.0), "p2": -0.01}]}),
            "frames[0]: lens distortion p2 = -0.01: dualphoton models pinhole cameras: undistort",
        ),
        ("no cameras", json!({"frames": []}), "no cameras"),
    ];
    for (name, calib, expected) in cases {
        std::fs::write(dir.join("calib.json"), calib.to_string()).unwrap();
        let err = calibration::load(&dir.join("calib.json")).unwrap_err().0;
        assert!(err.contains(expected) && !err.contains('\n'), "{name}: {err}");
    }
    // An image of another size than the calibration says.
    let calib = json!({"w": 8, "h": 4, "camera_angle_x": 0.5,
        "frames": [{"file_path": "one.png", "transform_matrix": looking_at_origin(0.0, 2.0)}]});
    std::fs::write(dir.join("calib.json"), calib.to_string()).unwrap();
    let capture = calibration::load(&dir.join("calib.json")).unwrap();
    let err = frames::read(&capture.views[0], &[0]).unwrap_err().0;
    assert!(err.contains("6x4") && err.contains("8x4"), "{err}");
}

#[test]
fn video_frames_decode_in_order_through_ffmpeg() {
    if !frames::have_ffmpeg() {
        eprintln!("SKIPPED video_frames_decode_in_order_through_ffmpeg: ffmpeg is not installed");
        return;
    }
    let dir = temp_dir("capture_video");
    // Eight flat grey frames, 40 + 20 n, coded with B-frames (x264's default).
    write_video(&dir, "cam", 8, (64, 48), |n, _, _| 40 + 20 * n);
    std::fs::copy(dir.join("cam.mp4"), dir.join("held.mp4")).unwrap();
    let calib = json!({
        "train_videos": [{"file_name": "cam.mp4", "frame_num": 8, "camera_angle_x": 0.5, "camera_hw": [48, 64],
                          "transform_matrix": looking_at_origin(0.0, 2.0)}],
        "test_videos": [{"file_name": "held.mp4", "frame_num": 8, "camera_angle_x": 0.5, "camera_hw": [48, 64],
                         "transform_matrix": looking_at_origin(2.0, 0.0)}],
        "voxel_matrix": [[1, 0, 0, -0.5], [0, 1, 0, -0.5], [0, 0, 1, -0.5], [0, 0, 0, 1]],
        "voxel_scale": [1.0, 1.0, 1.0],
    });
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    let capture = calibration::load(&dir.join("info.json")).unwrap();
    assert_eq!(capture.smoke_box, Some((Vec3::from_element(-0.5), Vec3::from_element(0.5))));
    assert!(!capture.views[0].held_out && capture.views[1].held_out);
    assert!(matches!(capture.views[0].frames, Frames::Video { count: 8, .. }));
    let got = frames::read(&capture.views[0], &[5, 1, 7, 5]).unwrap();
    for (image, n) in got.iter().zip([5.0, 1.0, 7.0, 5.0]) {
        let mean = image.data.iter().sum::<f64>() / image.data.len() as f64 * 255.0;
        // Limited-range video stretched back to full range: within 2 codes.
        assert!((mean - (40.0 + 20.0 * n)).abs() < 2.0, "frame {n}: mean code {mean}");
    }
    let err = frames::read(&capture.views[0], &[8]).unwrap_err().0;
    assert!(err.contains("frame 8 is out of range"), "{err}");
    // A calibration that claims more frames than the video has.
    let mut view = capture.views[0].clone();
    view.frames = Frames::Video { path: dir.join("cam.mp4"), count: 20 };
    let err = frames::read(&view, &[6, 12]).unwrap_err().0;
    assert!(err.contains("could not decode frames [6, 12]: the video ends before frame 12"), "{err}");
    // A calibration with width and height swapped: as many bytes a frame, refused all the same.
    let mut view = capture.views[0].clone();
    (view.camera.width, view.camera.height) = (48, 64);
    let err = frames::read(&view, &[1]).unwrap_err().0;
    assert!(err.contains("its frames are 64x48 but the calibration says 48x64"), "{err}");
}

#[test]
fn more_frames_than_one_ffmpeg_expression_takes_decode_in_order() {
    if !frames::have_ffmpeg() {
        eprintln!("SKIPPED more_frames_than_one_ffmpeg_expression_takes_decode_in_order: ffmpeg is not installed");
        return;
    }
    // 220 frames, each showing its number: the left half 40 + 10 (n mod 20),
    // the right half 40 + 10 (n div 20). ffmpeg's select filter refuses a
    // sum of over 100 terms; over 100 lone frames and a run are asked for here.
    let dir = temp_dir("capture_many_frames");
    let (left, right) = (|n: u16| 40 + 10 * (n % 20), |n: u16| 40 + 10 * (n / 20));
    write_video(&dir, "cam", 220, (32, 16), |n, x, _| if x < 16 { left(n) } else { right(n) });
    let calib = json!({
        "train_videos": [{"file_name": "cam.mp4", "frame_num": 220, "camera_angle_x": 0.5, "camera_hw": [16, 32],
                          "transform_matrix": looking_at_origin(0.0, 2.0)}],
    });
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    let capture = calibration::load(&dir.join("info.json")).unwrap();
    let mut wanted: Vec<usize> = (0..220).step_by(2).chain(150..160).rev().collect();
    wanted.push(77);
    let got = frames::read(&capture.views[0], &wanted).unwrap();
    assert_eq!(got.len(), wanted.len());
    for (image, &n) in got.iter().zip(&wanted) {
        // The middle four columns of each half, away from the edge between them.
        let code = |x0: usize| {
            let half = (0..16).flat_map(|y| (x0..x0 + 4).map(move |x| image.data[y * 32 + x]));
            half.sum::<f64>() / 64.0 * 255.0
        };
        let (l, r) = (code(6), code(22));
        assert!((l - left(n as u16) as f64).abs() < 3.0, "frame {n}: left half {l}");
        assert!((r - right(n as u16) as f64).abs() < 3.0, "frame {n}: right half {r}");
    }
}

#[test]
fn the_shipped_video_decodes_as_the_reference_decoder_decoded_it() {
    if !frames::have_ffmpeg() {
        eprintln!("SKIPPED the_shipped_video_decodes_as_the_reference_decoder_decoded_it: ffmpeg is not installed");
        return;
    }
    // tests/data/tiny_video: H.264 with B-frames (I B B B P B B P) and its
    // frames as PNG from the reference decoder; a spot moves about 6
    // pixels a frame, so a frame out of order is off by over 100 codes.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tiny_video");
    let dir = temp_dir("capture_tiny_video");
    std::fs::create_dir_all(dir.join("reference")).unwrap();
    std::fs::copy(data.join("tiny.mp4"), dir.join("tiny.mp4")).unwrap();
    for n in 0..8 {
        let name = format!("frame{n}.png");
        std::fs::copy(data.join(&name), dir.join("reference").join(&name)).unwrap();
    }
    let cam = |file: &str, x: f64, z: f64| json!({"file_name": file, "frame_num": 8, "camera_angle_x": 0.5, "camera_hw": [48, 64], "transform_matrix": looking_at_origin(x, z)});
    let calib = json!({"train_videos": [cam("tiny.mp4", 0.0, 2.0), cam("reference", 2.0, 0.0)]});
    std::fs::write(dir.join("info.json"), calib.to_string()).unwrap();
    let capture = calibration::load(&dir.join("info.json")).unwrap();
    assert!(matches!(capture.views[0].frames, Frames::Video { count: 8, .. }));
    let wanted = [6, 0, 7, 3, 6];
    let video = frames::read(&capture.views[0], &wanted).unwrap();
    let reference = frames::read(&capture.views[1], &wanted).unwrap();
    // Worst and mean difference in codes.
    let off = |a: &dualphoton::image::Image, b: &dualphoton::image::Image| {
        let codes = a.data.iter().zip(&b.data).map(|(x, y)| ((x - y) * 255.0).abs());
        let (worst, total) = codes.fold((0.0f64, 0.0), |(m, t), d| (m.max(d), t + d));
        (worst, total / a.data.len() as f64)
    };
    for (got, n) in video.iter().zip(wanted) {
        // Exact with the reference's ffmpeg; another version's colour
        // conversion may round codes the other way.
        let (worst, mean) = off(got, &reference[wanted.iter().position(|&m| m == n).unwrap()]);
        assert!(worst <= 2.0 + 1e-9 && mean <= 1.0, "frame {n}: {worst} codes off at worst, {mean} on average");
        // And far from every other frame: the order is right.
        for (other, m) in reference.iter().zip(wanted).filter(|&(_, m)| m != n) {
            assert!(off(got, other).1 > 5.0, "frame {n} decodes like frame {m}");
        }
    }
}

/// What other tools write is read as they mean it: instant-ngp's sizes as
/// floats, a camera's own field of view before a shared focal length, a
/// principal point beside a field of view, `.npy` frames with alpha or an
/// upper-case extension; and what cannot be meant is a one-line error: a
/// focal length of 0, a camera with a frame fewer, a negative brightness,
/// an unreadable image named for what is wrong with it.
#[test]
fn calibrations_and_frames_of_other_tools_are_read_as_they_mean() {
    let dir = temp_dir("capture_other_tools");
    for cam in ["a", "b"] {
        std::fs::create_dir_all(dir.join(cam)).unwrap();
        for n in 0..2u16 {
            write_png(&dir.join(cam).join(format!("{n}.png")), 6, 4, false, |x, _| 10 * n + x as u16);
        }
    }
    let load = |calib: Value| {
        std::fs::write(dir.join("transforms.json"), calib.to_string()).unwrap();
        calibration::load(&dir.join("transforms.json"))
    };
    let entry = |cam: &str, x: f64| json!({"file_path": cam, "transform_matrix": looking_at_origin(x, 2.0)});
    // Sizes as floats; a camera's own angles and principal point over the
    // top's focal length and principal point; the vertical angle over the height.
    let mut b = entry("b", 1.0);
    b["camera_angle_x"] = json!(0.5);
    b["camera_angle_y"] = json!(0.4);
    b["cx"] = json!(2.0);
    let top = json!({"w": 6.0, "h": 4.0, "fl_x": 9.0, "cx": 2.5, "cy": 1.5, "frames": [entry("a", 0.0), b]});
    let capture = load(top).unwrap();
    assert_eq!(capture.views[0].camera.intrinsics(), [9.0, 9.0, 2.5, 1.5]);
    let (fx, fy) = (3.0 / 0.25f64.tan(), 2.0 / 0.2f64.tan());
    assert_eq!(capture.views[1].camera.intrinsics(), [fx, fy, 2.0, 1.5]);
    // A focal length of 0, a size that is not whole.
    for (calib, says) in [
        (json!({"fl_x": 0.0, "frames": [entry("a", 0.0)]}), "fl_x: 0 must be a positive number of pixels"),
        (json!({"fl_x": 9.0, "fl_y": -9.0, "frames": [entry("a", 0.0)]}), "fl_y: -9 must be a positive"),
        (json!({"w": 6.5, "h": 4, "camera_angle_x": 0.5, "frames": [entry("a", 0.0)]}), "w: 6.5 is not a whole"),
    ] {
        let err = load(calib).unwrap_err().0;
        assert!(err.contains(says) && !err.contains('\n'), "{err}");
    }
    // A camera with a frame fewer: not paired with another instant's frames.
    std::fs::remove_file(dir.join("b/0.png")).unwrap();
    let err = load(json!({"camera_angle_x": 0.5, "frames": [entry("a", 0.0), entry("b", 1.0)]})).unwrap_err().0;
    assert!(err.contains("camera a has 2 frames, camera b 1"), "{err}");
    // Without w and h, an unreadable first image says why.
    std::fs::write(dir.join("b/0.png"), b"not a png").unwrap();
    let err = load(json!({"camera_angle_x": 0.5, "frames": [entry("b", 1.0)]})).unwrap_err().0;
    assert!(err.contains("give w and h") && err.contains("0.png: "), "{err}");
    // `.NPY` frames: grey and alpha composited over black as a PNG's; negative brightness refused.
    std::fs::create_dir_all(dir.join("c")).unwrap();
    let pixels: Vec<f64> = (0..24).flat_map(|i| [0.5, if i == 0 { 1.0 } else { 0.2 }]).collect();
    npy::write_f32(&dir.join("c/0.NPY"), &[4, 6, 2], &pixels).unwrap();
    let capture = load(json!({"camera_angle_x": 0.5, "frames": [entry("c", 0.0)]})).unwrap();
    let frame = frames::read(&capture.views[0], &[0]).unwrap().remove(0);
    assert_eq!((frame.data[0], frame.data[1]), (0.5, 0.5 * 0.2f32 as f64));
    npy::write_f32(&dir.join("c/0.NPY"), &[4, 6], &[vec![-0.25], vec![0.1; 23]].concat()).unwrap();
    let err = frames::read(&capture.views[0], &[0]).unwrap_err().0;
    assert!(err.contains("value -0.25 at pixel 0") && err.contains("negative"), "{err}");
}
