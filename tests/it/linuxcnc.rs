//! LinuxCNC's own kinematics modules as the reference (issue 24 item 5;
//! kinematics.md "Reference"; docs/linuxcnc-kinematics.md).
//!
//! Each module (`xyzac-trt-kins`, `xyzbc-trt-kins`, `xyzab_tdr_kins`, `5axiskins`,
//! `maxkins`) runs in a headless LinuxCNC 2.9 instance (Debian package
//! `linuxcnc-uspace`; `../shared/design/linuxcnc-headless.md`) with non-zero
//! parameters: `tests/data/linuxcnc/machine.ini.in` filled in here,
//! `headless.tcl` (motion, joints looped back) and `driver.py` (the "GUI": G53 G0
//! to each seeded tool-tip pose, then the joints and LinuxCNC's forward kinematics
//! of them). Every instance runs in its own PID, IPC and mount namespace with a
//! private `/tmp` and `/dev/shm`, two at a time.
//!
//! volcomp's machine for each module is a machine-file TOML string (what users
//! write: the preset and the chain form for the two trt modules, the chain for
//! the others). For every pose: the joints volcomp gives for LinuxCNC's commanded
//! tip (`tip_to_joints`) must equal LinuxCNC's joints, and volcomp's nominal tip at
//! LinuxCNC's joints (`nominal_tip`) must equal LinuxCNC's forward kinematics
//! (not for `maxkins`, whose forward kinematics is not the inverse of its inverse),
//! within 1e-6 mm / 1e-6 deg, after the documented convention mapping.
//!
//! A second test (issue 27 item 3) runs `trivkins` with the `COMP_FILE`s of
//! `volcomp export linuxcnc` and checks the screw compensation LinuxCNC applies
//! (`joint.N.motor-pos-cmd`, read through HAL) from each side of each target.
//!
//! The tests fail (never skip) when LinuxCNC cannot run. With
//! `VOLCOMP_WRITE_LINUXCNC_TABLE=1` it writes docs/linuxcnc-kinematics.md; otherwise
//! it fails when that page is stale.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use volcomp::axes::{Axes, Axis};
use volcomp::kinematics::Kinematics;
use volcomp::machine::{LoadOptions, Machine};

use crate::support;

/// Largest allowed difference, mm (linear) or degrees (rotary).
const TOLERANCE: f64 = 1e-6;
/// Poses per module.
const POSES: usize = 300;
/// Instances running at once.
const PARALLEL: usize = 2;
/// An instance that takes longer has hung.
const INSTANCE_TIMEOUT: Duration = Duration::from_secs(120);
/// World letters in LinuxCNC's order (`EmcPose`: X Y Z A B C U V W).
const LETTERS: &str = "XYZABCUVW";
const MODULE_DIR: &str = "/usr/lib/linuxcnc/modules";

/// One LinuxCNC kinematics module, its parameters and volcomp's equivalent machines.
struct Module {
    /// The module's name (`[KINS]KINEMATICS`' first word).
    name: &'static str,
    /// `[KINS]KINEMATICS` (module and its load parameters).
    kinematics: &'static str,
    /// `[TRAJ]COORDINATES`; joint k is letter k.
    coordinates: &'static str,
    /// HAL pins set before the run (`setp`), the module's parameters.
    parameters: Vec<(&'static str, f64)>,
    /// MDI commands before the poses (switching to the tool-tip kinematics).
    setup: &'static [&'static str],
    /// What the mapping to volcomp's convention adds to LinuxCNC's world Z and joint
    /// Z (the trt modules' `tool-offset`: both read the gauge point, volcomp's the tip).
    z_shift: f64,
    /// Ranges (degrees) of the rotary letters, in letter order.
    rotary: [(Axis, f64, f64); 2],
    /// Compare the forward direction too.
    forward: bool,
    /// volcomp's equivalent machines: (what, machine-file TOML).
    machines: Vec<(&'static str, String)>,
    /// The convention mapping, one line for the docs.
    mapping: &'static str,
}

/// A `[tool]` and wide `[limits]` that every machine below shares.
fn common_toml(tool_length: f64, rotary: &str) -> String {
    let mut limits = String::new();
    for l in rotary.chars() {
        writeln!(limits, "{} = [-1000.0, 1000.0]", l.to_ascii_lowercase()).unwrap();
    }
    format!(
        "[tool]\nlength = {tool_length:?}\nradius = 1.0\n\n\
         [limits]\nx = [-100000.0, 100000.0]\ny = [-100000.0, 100000.0]\nz = [-100000.0, 100000.0]\n{limits}"
    )
}

fn modules() -> Vec<Module> {
    // xyzac-trt-kins: the contract's xyzac-trt (kinematics.md), P_C the rot point,
    // P_A = P_C + (0, y-offset, z-offset). x-offset is ignored by the module.
    let (xr, yr, zr, dx, dy, dz, dt) = (12.5, -7.25, 30.5, 3.0, 20.25, -15.5, 85.75);
    let ac_preset = format!(
        "name = \"lcnc-xyzac\"\nkinematics = \"xyzac-trt\"\n\n[geometry]\n\
         x_rot_point = {xr:?}\ny_rot_point = {yr:?}\nz_rot_point = {zr:?}\ny_offset = {dy:?}\nz_offset = {dz:?}\n\n{}",
        common_toml(dt, "AC")
    );
    let ac_chain = format!(
        "name = \"lcnc-xyzac-chain\"\nkinematics = \"chain\"\nworkpiece_side = [\"A\", \"C\"]\n\
         tool_side = [\"X\", \"Y\", \"Z\"]\n\n\
         [axes.A]\ndirection = [1.0, 0.0, 0.0]\npoint = [{xr:?}, {:?}, {:?}]\n\
         [axes.C]\ndirection = [0.0, 0.0, 1.0]\npoint = [{xr:?}, {yr:?}, {zr:?}]\n\n{}",
        yr + dy,
        zr + dz,
        common_toml(dt, "AC")
    );
    let xyzac = Module {
        name: "xyzac-trt-kins",
        kinematics: "xyzac-trt-kins",
        coordinates: "XYZAC",
        parameters: vec![
            ("x-rot-point", xr),
            ("y-rot-point", yr),
            ("z-rot-point", zr),
            ("x-offset", dx),
            ("y-offset", dy),
            ("z-offset", dz),
            ("tool-offset", dt),
        ],
        setup: &[],
        z_shift: dt,
        rotary: [(Axis::A, -120.0, 120.0), (Axis::C, -360.0, 360.0)],
        forward: true,
        machines: vec![("`xyzac-trt` preset", ac_preset), ("chain", ac_chain)],
        mapping: "world Z and joint Z = volcomp's + tool-offset; x-offset is ignored by the module",
    };

    // xyzbc-trt-kins: B (about +Y) in place of A, P_B = P_C + (x-offset, 0, z-offset).
    let (xr, yr, zr, dx, dy, dz, dt) = (-9.5, 4.75, 25.0, 18.5, 6.0, -12.25, 64.5);
    let bc_preset = format!(
        "name = \"lcnc-xyzbc\"\nkinematics = \"xyzbc-trt\"\n\n[geometry]\n\
         x_rot_point = {xr:?}\ny_rot_point = {yr:?}\nz_rot_point = {zr:?}\nx_offset = {dx:?}\nz_offset = {dz:?}\n\n{}",
        common_toml(dt, "BC")
    );
    let bc_chain = format!(
        "name = \"lcnc-xyzbc-chain\"\nkinematics = \"chain\"\nworkpiece_side = [\"B\", \"C\"]\n\
         tool_side = [\"X\", \"Y\", \"Z\"]\n\n\
         [axes.B]\ndirection = [0.0, 1.0, 0.0]\npoint = [{:?}, {yr:?}, {:?}]\n\
         [axes.C]\ndirection = [0.0, 0.0, 1.0]\npoint = [{xr:?}, {yr:?}, {zr:?}]\n\n{}",
        xr + dx,
        zr + dz,
        common_toml(dt, "BC")
    );
    let xyzbc = Module {
        name: "xyzbc-trt-kins",
        kinematics: "xyzbc-trt-kins",
        coordinates: "XYZBC",
        parameters: vec![
            ("x-rot-point", xr),
            ("y-rot-point", yr),
            ("z-rot-point", zr),
            ("x-offset", dx),
            ("y-offset", dy),
            ("z-offset", dz),
            ("tool-offset", dt),
        ],
        setup: &[],
        z_shift: dt,
        rotary: [(Axis::B, -120.0, 120.0), (Axis::C, -360.0, 360.0)],
        forward: true,
        machines: vec![("`xyzbc-trt` preset", bc_preset), ("chain", bc_chain)],
        mapping: "world Z and joint Z = volcomp's + tool-offset; y-offset is ignored by the module",
    };

    // xyzab_tdr_kins (type 1, tool-tip): B on the bed about −Y through the rot
    // point, A on B about −X through rot point + (0, 0, z-offset); x-offset cancels.
    let (xr, yr, zr, dx, dz, dt) = (7.5, -11.25, 40.0, 9.0, 22.5, 50.25);
    let ab_chain = format!(
        "name = \"lcnc-xyzab-tdr\"\nkinematics = \"chain\"\nworkpiece_side = [\"B\", \"A\"]\n\
         tool_side = [\"X\", \"Y\", \"Z\"]\n\n\
         [axes.B]\ndirection = [0.0, -1.0, 0.0]\npoint = [{xr:?}, {yr:?}, {zr:?}]\n\
         [axes.A]\ndirection = [-1.0, 0.0, 0.0]\npoint = [{xr:?}, {yr:?}, {:?}]\n\n{}",
        zr + dz,
        common_toml(dt, "AB")
    );
    let xyzab = Module {
        name: "xyzab_tdr_kins",
        kinematics: "xyzab_tdr_kins",
        coordinates: "XYZAB",
        parameters: vec![
            ("x-rot-point", xr),
            ("y-rot-point", yr),
            ("z-rot-point", zr),
            ("x-offset", dx),
            ("z-offset", dz),
            ("tool-offset-z", dt),
        ],
        setup: &["M68 E3 Q1", "M66 E0 L0"],
        z_shift: dt,
        rotary: [(Axis::A, -120.0, 120.0), (Axis::B, -120.0, 120.0)],
        forward: true,
        machines: vec![("chain", ab_chain)],
        mapping: "type 1 (M68 E3 Q1); B outer (on the bed) and A on it, both turning the table \
                  the conventional way (directions −Y, −X); world Z and joint Z = volcomp's + \
                  tool-offset-z; x-offset cancels out",
    };

    // 5axiskins: a B/C head on X Y Z; the pivot (both axes) pivot-length above the
    // tip at home; LinuxCNC's pivot-length = the head's own + the tool length.
    let (pivot, tool) = (180.25, 70.25);
    let head_head = format!(
        "name = \"lcnc-5axis\"\nkinematics = \"chain\"\nworkpiece_side = []\n\
         tool_side = [\"X\", \"Y\", \"Z\", \"C\", \"B\"]\n\n\
         [axes.C]\ndirection = [0.0, 0.0, 1.0]\npoint = [0.0, 0.0, {pivot:?}]\n\
         [axes.B]\ndirection = [0.0, -1.0, 0.0]\npoint = [0.0, 0.0, {pivot:?}]\n\n{}",
        common_toml(tool, "BC")
    );
    let fiveaxis = Module {
        name: "5axiskins",
        kinematics: "5axiskins coordinates=XYZBCW",
        coordinates: "XYZBCW",
        parameters: vec![("pivot-length", pivot + tool)],
        setup: &[],
        z_shift: 0.0,
        rotary: [(Axis::B, -120.0, 120.0), (Axis::C, -360.0, 360.0)],
        forward: true,
        machines: vec![("chain", head_head)],
        mapping: "pivot-length = the chain's pivot (points [0, 0, p], relative to the gauge \
                  point) + the tool length; B turns about −Y; W = 0",
    };

    // maxkins: a B head on X Y Z (pivot as 5axiskins), C a table about −Z through
    // the machine origin.
    let (pivot, tool) = (80.25, 40.5);
    let head_table = format!(
        "name = \"lcnc-max\"\nkinematics = \"chain\"\nworkpiece_side = [\"C\"]\n\
         tool_side = [\"X\", \"Y\", \"Z\", \"B\"]\n\n\
         [axes.C]\ndirection = [0.0, 0.0, -1.0]\npoint = [0.0, 0.0, 0.0]\n\
         [axes.B]\ndirection = [0.0, -1.0, 0.0]\npoint = [0.0, 0.0, {pivot:?}]\n\n{}",
        common_toml(tool, "BC")
    );
    let max = Module {
        name: "maxkins",
        kinematics: "maxkins",
        coordinates: "XYZABCUVW",
        parameters: vec![("pivot-length", pivot + tool)],
        setup: &[],
        z_shift: 0.0,
        rotary: [(Axis::B, -120.0, 120.0), (Axis::C, -360.0, 360.0)],
        forward: false,
        machines: vec![("chain", head_table)],
        mapping: "pivot-length as 5axiskins; C turns the table about −Z through the machine \
                  origin; A U V W = 0; inverse direction only",
    };
    vec![xyzac, xyzbc, xyzab, fiveaxis, max]
}

/// SplitMix64: a seeded, portable stream of poses.
struct Seeded(u64);

impl Seeded {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi], rounded to 1e-6 (the driver sends 10 decimals).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        ((lo + (hi - lo) * self.next()) * 1e6).round() / 1e6
    }
}

/// The world poses (LinuxCNC's X Y Z A B C U V W) of a module.
fn poses(module: &Module, seed: u64) -> Vec<[f64; 9]> {
    let mut rng = Seeded(seed);
    (0..POSES)
        .map(|_| {
            let mut p = [0.0; 9];
            for v in p.iter_mut().take(3) {
                *v = rng.uniform(-150.0, 150.0);
            }
            p[2] += module.z_shift;
            for (axis, lo, hi) in module.rotary {
                p[LETTERS.find(axis.letter()).unwrap()] = rng.uniform(lo, hi);
            }
            p
        })
        .collect()
}

/// What LinuxCNC reported for one pose.
#[derive(Debug)]
struct Record {
    world: [f64; 9],
    joints: Vec<f64>,
    actual: [f64; 9],
    /// `joint.N.motor-pos-cmd` of [`Instance::comp`]'s joints, in that order.
    motor: Vec<f64>,
}

/// What an instance has besides its module.
#[derive(Default)]
struct Instance {
    /// (joint, `COMP_FILE`, `COMP_FILE_TYPE`): screw compensation of those joints,
    /// whose `motor-pos-cmd` the driver reports.
    comp: Vec<(usize, PathBuf, u8)>,
    /// Per pose: a feed (mm/min) for a G53 G1 move there, or 0 for G53 G0; empty:
    /// all G0.
    feeds: Vec<f64>,
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2).map(|e| e == "0"))
        })
        .unwrap_or(false)
}

/// Everything a headless instance needs, or a panic that says what is missing.
fn check_linuxcnc() {
    let mut missing = Vec::new();
    for (program, what) in [
        (
            "linuxcnc",
            "the `linuxcnc` script (Debian package linuxcnc-uspace)",
        ),
        ("halrun", "`halrun` (linuxcnc-uspace)"),
        ("haltcl", "`haltcl` (linuxcnc-uspace; runs headless.tcl)"),
        ("rtapi_app", "`rtapi_app` (linuxcnc-uspace)"),
        ("unshare", "`unshare` (util-linux)"),
    ] {
        let found = std::env::var_os("PATH")
            .is_some_and(|paths| std::env::split_paths(&paths).any(|d| d.join(program).is_file()));
        if !found {
            missing.push(what.to_string());
        }
    }
    for module in modules() {
        let so = Path::new(MODULE_DIR).join(format!("{}.so", module.name));
        if !so.is_file() {
            missing.push(format!("{} (linuxcnc-uspace)", so.display()));
        }
    }
    let python = Command::new("/usr/bin/python3")
        .args(["-c", "import linuxcnc"])
        .output();
    if !python.is_ok_and(|o| o.status.success()) {
        missing.push(
            "the `linuxcnc` Python module for /usr/bin/python3 (linuxcnc-uspace)".to_string(),
        );
    }
    if !is_root() {
        missing.push(
            "root: each instance runs in its own PID/IPC/mount namespace (unshare) and \
             rtapi_app needs root"
                .to_string(),
        );
    }
    assert!(
        missing.is_empty(),
        "LinuxCNC's kinematics modules cannot run headless here (.ci/run installs what is \
         needed; see docs/linuxcnc-kinematics.md). Missing:\n  {}",
        missing.join("\n  ")
    );
}

fn data_dir() -> PathBuf {
    support::root().join("tests/data/linuxcnc")
}

/// The INI of `module`'s instance in `dir`.
fn ini(module: &Module, dir: &Path) -> String {
    let template = std::fs::read_to_string(data_dir().join("machine.ini.in")).unwrap();
    let prefix = module.name;
    let halcmd: String = module
        .parameters
        .iter()
        .map(|(pin, v)| format!("HALCMD = setp {prefix}.{pin} {v:?}\n"))
        .collect();
    let mut axes = String::new();
    let mut letters: Vec<char> = module.coordinates.chars().collect();
    letters.dedup();
    for l in &letters {
        writeln!(
            axes,
            "[AXIS_{l}]\nMIN_LIMIT = -100000\nMAX_LIMIT = 100000\nMAX_VELOCITY = 100000\n\
             MAX_ACCELERATION = 10000000\n"
        )
        .unwrap();
    }
    let mut joints = String::new();
    for (j, l) in module.coordinates.chars().enumerate() {
        let kind = if "ABC".contains(l) {
            "ANGULAR"
        } else {
            "LINEAR"
        };
        writeln!(
            joints,
            "[JOINT_{j}]\nTYPE = {kind}\nHOME = 0\nMIN_LIMIT = -100000\nMAX_LIMIT = 100000\n\
             MAX_VELOCITY = 100000\nMAX_ACCELERATION = 10000000\nFERROR = 1000000\n\
             MIN_FERROR = 1000000\nHOME_SEARCH_VEL = 0\nHOME_LATCH_VEL = 0\nHOME_SEQUENCE = 0\n"
        )
        .unwrap();
    }
    template
        .replace("@NAME@", module.name)
        .replace(
            "@DRIVER@",
            &data_dir().join("driver.py").display().to_string(),
        )
        .replace("@KINEMATICS@", module.kinematics)
        .replace("@JOINTS@", &module.coordinates.len().to_string())
        .replace("@COORDINATES@", module.coordinates)
        .replace("@DIR@", &dir.display().to_string())
        .replace(
            "@HALFILE@",
            &data_dir().join("headless.tcl").display().to_string(),
        )
        .replace("@HALCMD@", &halcmd)
        .replace("@AXES@", &axes)
        .replace("@JOINT_SECTIONS@", &joints)
}

/// The last lines of LinuxCNC's logs in `dir`, for a failure message.
fn logs(dir: &Path) -> String {
    let mut text = String::new();
    for name in ["linuxcnc_print.txt", "linuxcnc_debug.txt", "console.txt"] {
        let content = std::fs::read_to_string(dir.join(name)).unwrap_or_default();
        let lines: Vec<&str> = content.lines().collect();
        let tail = lines[lines.len().saturating_sub(15)..].join("\n    ");
        write!(text, "\n  {name}:\n    {tail}").unwrap();
    }
    text
}

fn numbers(words: &[&str]) -> Vec<f64> {
    words.iter().map(|w| w.parse::<f64>().unwrap()).collect()
}

fn nine(words: &[&str]) -> [f64; 9] {
    numbers(words).try_into().unwrap()
}

/// Runs `module` headless on `poses` and returns what LinuxCNC reported.
fn run_instance(module: &Module, poses: &[[f64; 9]], instance: &Instance) -> Vec<Record> {
    let base = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    std::fs::create_dir_all(&base).unwrap();
    let dir = tempfile::Builder::new()
        .prefix(&format!("linuxcnc-{}-", module.name))
        .tempdir_in(&base)
        .unwrap();
    let dir_path = dir.path();
    let private_tmp = dir_path.join("tmp");
    std::fs::create_dir(&private_tmp).unwrap();
    // rtapi_app runs as the fallback user 65534 and makes its socket there.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&private_tmp, std::fs::Permissions::from_mode(0o1777)).unwrap();
    std::fs::write(dir_path.join("tool.tbl"), "").unwrap();
    let ini_path = dir_path.join("machine.ini");
    let mut ini_text = ini(module, dir_path);
    for (joint, file, kind) in &instance.comp {
        let section = format!("[JOINT_{joint}]\n");
        assert!(ini_text.contains(&section), "no {section}");
        ini_text = ini_text.replace(
            &section,
            &format!(
                "{section}COMP_FILE = {}\nCOMP_FILE_TYPE = {kind}\n",
                file.display()
            ),
        );
    }
    std::fs::write(&ini_path, ini_text).unwrap();
    let motor_joints: Vec<String> = instance.comp.iter().map(|c| c.0.to_string()).collect();
    let mut commands = String::new();
    for s in module.setup {
        writeln!(commands, "setup {s}").unwrap();
    }
    for (k, p) in poses.iter().enumerate() {
        let words: Vec<String> = p.iter().map(|v| format!("{v:?}")).collect();
        match instance.feeds.get(k) {
            Some(&f) if f > 0.0 => writeln!(commands, "feed {f:?} {}", words.join(" ")),
            _ => writeln!(commands, "pose {}", words.join(" ")),
        }
        .unwrap();
    }
    let poses_path = dir_path.join("poses.txt");
    std::fs::write(&poses_path, commands).unwrap();
    let out_path = dir_path.join("joints.txt");
    let console = std::fs::File::create(dir_path.join("console.txt")).unwrap();
    // The instance's /tmp is its own folder, mounted over /tmp. What the run
    // reads from the checkout (the HAL file, the INI, comp files) is mounted
    // back at its own path on top when it lives under /tmp (the original
    // /tmp staged at /mnt, in this namespace only).
    let mut back = String::new();
    for needed in [Path::new(env!("CARGO_MANIFEST_DIR")), base.as_path()] {
        if let Ok(rest) = needed.strip_prefix("/tmp")
            && let Some(top) = rest.components().next()
        {
            let top = Path::new(top.as_os_str());
            write!(
                back,
                " && mkdir -p '/tmp/{t}' && mount --bind '/mnt/{t}' '/tmp/{t}'",
                t = top.display()
            )
            .unwrap();
        }
    }
    let script = format!(
        "mount --bind /tmp /mnt && mount --bind '{tmp}' /tmp{back} \
         && mount -t tmpfs tmpfs /dev/shm && exec linuxcnc '{ini}'",
        tmp = private_tmp.display(),
        ini = ini_path.display()
    );
    let mut child = Command::new("unshare")
        .args([
            "--fork",
            "--pid",
            "--mount-proc",
            "--ipc",
            "--mount",
            "--net",
            "--kill-child",
        ])
        .args(["sh", "-c", &script])
        .current_dir(dir_path)
        .env("HOME", dir_path)
        .env("RTAPI_UID", "65534")
        .env("RTAPI_FIFO_PATH", "/tmp/rtapi_fifo")
        .env("VOLCOMP_LINUXCNC_POSES", &poses_path)
        .env("VOLCOMP_LINUXCNC_OUT", &out_path)
        .env("VOLCOMP_LINUXCNC_MOTOR", motor_joints.join(" "))
        .stdin(Stdio::null())
        .stdout(console.try_clone().unwrap())
        .stderr(console)
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start `unshare … linuxcnc`: {e}"));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > INSTANCE_TIMEOUT {
            // --kill-child: the namespace's processes die with unshare.
            child.kill().ok();
            child.wait().ok();
            let logs = logs(dir_path);
            panic!(
                "{}: LinuxCNC did not finish within {INSTANCE_TIMEOUT:?}{logs}\n  (instance kept in {})",
                module.name,
                dir.keep().display()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let partial = std::fs::read_to_string(out_path.with_extension("txt.part")).unwrap_or_default();
    let Ok(text) = std::fs::read_to_string(&out_path) else {
        let error = partial
            .lines()
            .find(|l| l.starts_with("error"))
            .unwrap_or("no result written");
        let logs = logs(dir_path);
        panic!(
            "{}: the headless LinuxCNC run failed ({status}): {error}{logs}\n  (instance kept in {})",
            module.name,
            dir.keep().display()
        );
    };
    let joints = module.coordinates.len();
    let mut records = Vec::new();
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.first() == Some(&"done") {
            break;
        }
        assert_eq!(w[0], "pose", "{}: unexpected line {line}", module.name);
        assert_eq!(w[1].parse::<usize>().unwrap(), records.len());
        assert_eq!(w[2], "world");
        assert_eq!(w[12], "joints");
        assert_eq!(w[13 + joints], "actual");
        let motor = if instance.comp.is_empty() {
            Vec::new()
        } else {
            assert_eq!(w.get(23 + joints), Some(&"motor"), "{line}");
            numbers(&w[24 + joints..])
        };
        assert_eq!(motor.len(), instance.comp.len(), "{line}");
        records.push(Record {
            world: nine(&w[3..12]),
            joints: numbers(&w[13..13 + joints]),
            actual: nine(&w[14 + joints..23 + joints]),
            motor,
        });
    }
    assert!(
        text.lines().last() == Some("done") && records.len() == poses.len(),
        "{}: {} of {} poses reported",
        module.name,
        records.len(),
        poses.len()
    );
    records
}

/// The largest differences of one volcomp machine against one module's run.
#[derive(Clone, Copy, Debug, Default)]
struct Agreement {
    inverse_mm: f64,
    inverse_deg: f64,
    forward_mm: f64,
    forward_deg: f64,
    /// `maxkins` only: LinuxCNC's forward kinematics against volcomp's tip with the
    /// head offset left unrotated by C (the module's quirk, see [`maxkins_forward`]).
    quirk_mm: f64,
}

/// What `maxkins`' forward kinematics computes, in volcomp's terms: the table's
/// rotation applied to the linear joints only, `R_z(c)·(x, y, z) + h(b)`, where the
/// head's offset `h(b)` (tip minus linear joints, machine frame) should turn with
/// the table too (its inverse does turn it: `(x, y, z) = R_z(−c)·tip − h(b)`).
fn maxkins_forward(kin: &Kinematics, joints: &Axes) -> [f64; 3] {
    let head = Axes {
        b: joints.b,
        ..Axes::default()
    };
    let h = kin.nominal_tip(&head);
    let (s, c) = joints.c.to_radians().sin_cos();
    [
        c * joints.x - s * joints.y + h[0],
        s * joints.x + c * joints.y + h[1],
        joints.z + h[2],
    ]
}

fn letter_at(i: usize) -> Axis {
    Axis::from_letter(LETTERS.as_bytes()[i] as char).unwrap()
}

fn compare(module: &Module, kin: &Kinematics, records: &[Record]) -> Agreement {
    let mut worst = Agreement::default();
    let letters: Vec<Axis> = module
        .coordinates
        .chars()
        .map(|c| Axis::from_letter(c).unwrap())
        .collect();
    let world_of = |p: &[f64; 9], axis: Axis| p[LETTERS.find(axis.letter()).unwrap()];
    for r in records {
        // Inverse: LinuxCNC's commanded tip → volcomp's joints.
        let mut rotaries = Axes::default();
        for (axis, _, _) in module.rotary {
            rotaries.set(axis, world_of(&r.world, axis));
        }
        let tip = [r.world[0], r.world[1], r.world[2] - module.z_shift];
        let q = kin.tip_to_joints(&rotaries).joints(tip);
        for (k, axis) in letters.iter().enumerate() {
            let expected = match axis {
                Axis::X | Axis::Y => q.get(*axis),
                Axis::Z => q.z + module.z_shift,
                a if a.is_rotary() && module.rotary.iter().any(|(b, _, _)| b == a) => q.get(*a),
                // Letters the chain does not have (5axiskins' W, maxkins' A U V W):
                // commanded 0, joint 0.
                a => world_of(&r.world, *a),
            };
            let d = (r.joints[k] - expected).abs();
            if axis.is_rotary() {
                worst.inverse_deg = worst.inverse_deg.max(d);
            } else {
                worst.inverse_mm = worst.inverse_mm.max(d);
            }
        }
        // Forward: LinuxCNC's joints → volcomp's nominal tip.
        let mut joints = Axes::default();
        for (k, axis) in letters.iter().enumerate() {
            if !axis.is_rotary() && !matches!(axis, Axis::X | Axis::Y | Axis::Z) {
                continue;
            }
            let shift = if *axis == Axis::Z {
                module.z_shift
            } else {
                0.0
            };
            joints.set(*axis, r.joints[k] - shift);
        }
        let tip = kin.nominal_tip(&joints);
        let actual = [r.actual[0], r.actual[1], r.actual[2] - module.z_shift];
        let quirk = (!module.forward).then(|| maxkins_forward(kin, &joints));
        for i in 0..3 {
            worst.forward_mm = worst.forward_mm.max((tip[i] - actual[i]).abs());
            if let Some(q) = quirk {
                worst.quirk_mm = worst.quirk_mm.max((q[i] - actual[i]).abs());
            }
        }
        for (axis, _, _) in module.rotary {
            let i = LETTERS.find(axis.letter()).unwrap();
            assert_eq!(letter_at(i), axis);
            worst.forward_deg = worst
                .forward_deg
                .max((r.actual[i] - joints.get(axis)).abs());
        }
    }
    worst
}

/// `< 1e-N`, the power of ten above `v` (the table stays the same across libm
/// versions unless a difference crosses a power of ten).
fn bound(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("< 1e{}", v.log10().floor() as i32 + 1)
    }
}

#[test]
fn linuxcnc_kinematics_modules_agree_with_the_chain() {
    check_linuxcnc();
    let started = Instant::now();
    let modules = modules();
    let queue: Mutex<Vec<usize>> = Mutex::new((0..modules.len()).rev().collect());
    let results: Mutex<Vec<Option<Result<Vec<Record>, String>>>> =
        Mutex::new((0..modules.len()).map(|_| None).collect());
    let all_poses: Vec<Vec<[f64; 9]>> = modules
        .iter()
        .enumerate()
        .map(|(i, m)| poses(m, 0x5eed_0000 + i as u64))
        .collect();
    std::thread::scope(|scope| {
        for _ in 0..PARALLEL {
            scope.spawn(|| {
                loop {
                    let Some(i) = queue.lock().unwrap().pop() else {
                        break;
                    };
                    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        run_instance(&modules[i], &all_poses[i], &Instance::default())
                    }))
                    .map_err(|e| {
                        e.downcast_ref::<String>()
                            .cloned()
                            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                            .unwrap_or_default()
                    });
                    results.lock().unwrap()[i] = Some(run);
                }
            });
        }
    });
    let results = results.into_inner().unwrap();
    let mut failures = Vec::new();
    let mut rows = Vec::new();
    let mut printed = String::new();
    for (module, result) in modules.iter().zip(results) {
        let records = match result.expect("every module ran") {
            Ok(r) => r,
            Err(e) => {
                failures.push(e);
                continue;
            }
        };
        for (what, toml) in &module.machines {
            let machine = Machine::parse(
                toml,
                Path::new("linuxcnc-equivalent.toml"),
                &LoadOptions::default(),
            )
            .unwrap_or_else(|e| panic!("{} ({what}): {e}\n{toml}", module.name));
            let kin = machine.kinematics_model();
            let w = compare(module, &kin, &records);
            // The poses exercise the rotary axes: the same machine with both rotary
            // axes turning the other way disagrees.
            let reversed =
                Kinematics::from_chain(kin.chain.with_negated_rotaries(), kin.tool_length);
            let control = compare(module, &reversed, &records);
            if control.inverse_mm < 1.0 {
                failures.push(format!(
                    "{} ({what}): the reversed machine agrees too ({:e} mm): the poses do not test the rotary axes",
                    module.name, control.inverse_mm
                ));
            }
            if !module.forward && w.quirk_mm > TOLERANCE {
                failures.push(format!(
                    "{} ({what}): its forward kinematics is no longer R_z(c)·(x, y, z) + h(b) ({:e} mm)",
                    module.name, w.quirk_mm
                ));
            }
            writeln!(
                printed,
                "{:<16} {:<20} {} poses: inverse {:.2e} mm {:.2e} deg, forward {:.2e} mm {:.2e} deg \
                 (reversed rotaries: inverse {:.1} mm){}",
                module.name,
                what,
                records.len(),
                w.inverse_mm,
                w.inverse_deg,
                w.forward_mm,
                w.forward_deg,
                control.inverse_mm,
                if module.forward {
                    String::new()
                } else {
                    format!(", quirk formula {:.2e} mm", w.quirk_mm)
                }
            )
            .unwrap();
            if w.inverse_mm > TOLERANCE || w.inverse_deg > TOLERANCE {
                failures.push(format!(
                    "{} ({what}): inverse differs by {:e} mm / {:e} deg",
                    module.name, w.inverse_mm, w.inverse_deg
                ));
            }
            if module.forward && (w.forward_mm > TOLERANCE || w.forward_deg > TOLERANCE) {
                failures.push(format!(
                    "{} ({what}): forward differs by {:e} mm / {:e} deg",
                    module.name, w.forward_mm, w.forward_deg
                ));
            }
            let forward = if module.forward {
                format!("{} | {}", bound(w.forward_mm), bound(w.forward_deg))
            } else {
                format!(
                    "not compared: up to {:.0} mm off; R_z(c)·(x, y, z) + h(b) matches {} | {}",
                    w.forward_mm,
                    bound(w.quirk_mm),
                    bound(w.forward_deg)
                )
            };
            let parameters: Vec<String> = module
                .parameters
                .iter()
                .map(|(p, v)| format!("{p} {v}"))
                .collect();
            rows.push(format!(
                "| `{}` | {what}, tool length {} mm | {} | {} | {} | {} | {forward} |",
                module.name,
                kin.tool_length,
                parameters.join(", "),
                records.len(),
                bound(w.inverse_mm),
                bound(w.inverse_deg),
            ));
        }
    }
    println!("{printed}({:.1} s)", started.elapsed().as_secs_f64());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    let mut mappings = String::new();
    for m in &modules {
        writeln!(mappings, "- `{}`: {}.", m.name, m.mapping).unwrap();
    }
    let table = format!(
        "| module | volcomp machine | parameters (HAL pins) | poses | inverse max \\|Δ\\| mm | \
         inverse max \\|Δ\\| deg | forward max \\|Δ\\| mm | forward max \\|Δ\\| deg |\n\
         |---|---|---|---|---|---|---|---|\n{}\n",
        rows.join("\n")
    );
    let path = support::root().join("docs/linuxcnc-kinematics.md");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    let (head, tail) = split_generated(&committed);
    let doc = format!("{head}{BEGIN}\n{table}\n{mappings}{END}{tail}");
    if std::env::var("VOLCOMP_WRITE_LINUXCNC_TABLE").is_ok_and(|v| v == "1") {
        std::fs::write(&path, &doc).unwrap();
    } else {
        assert!(
            committed == doc,
            "docs/linuxcnc-kinematics.md is stale: run \
             VOLCOMP_WRITE_LINUXCNC_TABLE=1 cargo test --release --locked --test it linuxcnc::"
        );
    }
}

const BEGIN: &str = "<!-- generated by tests/it/linuxcnc.rs: begin -->";
const END: &str = "<!-- generated by tests/it/linuxcnc.rs: end -->";

/// The hand-written parts of the page around the generated table.
fn split_generated(doc: &str) -> (&str, &str) {
    match (doc.find(BEGIN), doc.find(END)) {
        (Some(b), Some(e)) if b < e => (&doc[..b], &doc[e + END.len()..]),
        _ => (doc, "\n"),
    }
}

/// Feed (mm/min) of the last 0.05 mm to each target of the screw-comp instance.
/// Motion takes the trim at the commanded position of the last servo period in
/// which the joint moved (`compute_screw_comp` keeps it while `vel_cmd` is 0). With
/// the template's near-unlimited acceleration a G0 ends in a period or two, the last
/// moving one millimetres short of the target (trims off by up to 6e-5 mm,
/// measured); at F6 (0.1 mm/s, 1 ms period) it is at most 1e-4 mm short, the trim off
/// by the file's slope (≤ 2e-3) times that.
const FINAL_FEED: f64 = 6.0;

/// `volcomp export linuxcnc` into `dir` with `--comp-type`; the written directory.
fn export_comp(machine: &Path, dir: &Path, comp_type: u8) -> PathBuf {
    let out = dir.join(format!("type{comp_type}"));
    let run = support::volcomp()
        .args(["export", "linuxcnc"])
        .arg(machine)
        .arg("-o")
        .arg(&out)
        .args(["--comp-type", &comp_type.to_string()])
        .output()
        .unwrap();
    support::assert_success(&run);
    out
}

/// Issue 27 item 3: LinuxCNC itself (trivkins, joints looped back) with the
/// `COMP_FILE`s of `volcomp export linuxcnc` puts the joint where the file says.
/// X: type 0 (actual positions) of ref-trt with the laser import of
/// tests/data/laser/x-long.csv (REVERSAL 5 to 7 µm, so up and down differ); Y: type
/// 1 (trims). Each target is approached from below (5 mm under it, then it) and from
/// above; `joint.N.motor-pos-cmd` − commanded must equal the trim LinuxCNC's
/// `compute_screw_comp` interpolates from the file for that direction (the last
/// direction of motion), within 1e-6 mm.
#[test]
fn linuxcnc_screw_comp_applies_the_exported_comp_files() {
    check_linuxcnc();
    let so = Path::new(MODULE_DIR).join("trivkins.so");
    assert!(
        so.is_file(),
        "{} (linuxcnc-uspace) is missing",
        so.display()
    );
    let started = Instant::now();
    // Under the test's folder, which every instance sees at its own path.
    let base = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    std::fs::create_dir_all(&base).unwrap();
    let dir = tempfile::tempdir_in(&base).unwrap();
    let machine = crate::export::machine_with_reversal(dir.path());
    let type0 = export_comp(&machine, dir.path(), 0);
    let type1 = export_comp(&machine, dir.path(), 1);
    let files = [
        (0usize, type0.join("x.comp"), 0u8),
        (1, type1.join("y.comp"), 1),
    ];
    let tables: Vec<Vec<(f64, f64, f64)>> = files
        .iter()
        .map(|(_, f, t)| crate::export::linuxcnc_load(&std::fs::read_to_string(f).unwrap(), *t))
        .collect();
    for t in &tables {
        assert!(t.len() > 2, "a comp file with {} triplets", t.len());
    }
    let module = Module {
        name: "trivkins",
        kinematics: "trivkins",
        coordinates: "XYZ",
        parameters: vec![],
        setup: &[],
        z_shift: 0.0,
        rotary: [(Axis::A, 0.0, 0.0), (Axis::C, 0.0, 0.0)],
        forward: true,
        machines: vec![],
        mapping: "",
    };
    // (X, Y) targets: inside the tables, on a nominal, and beyond the ends.
    let targets = [
        (-187.654321, -143.21),
        (-40.0, -3.333333),
        (12.345678, 57.77),
        (133.3, 110.0),
        (205.0, 160.5),
    ];
    let mut poses = Vec::new();
    let mut feeds = Vec::new();
    for &(x, y) in &targets {
        for side in [-1.0, 1.0] {
            for (d, f) in [(5.0, 0.0), (0.05, 0.0), (0.0, FINAL_FEED)] {
                poses.push([
                    x + side * d,
                    y + side * d,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ]);
                feeds.push(f);
            }
        }
    }
    let records = run_instance(
        &module,
        &poses,
        &Instance {
            comp: files.to_vec(),
            feeds,
        },
    );
    let mut worst: f64 = 0.0;
    let mut failures = Vec::new();
    let mut table = String::from(
        "| joint | COMP_FILE_TYPE | target mm | approach | expected trim mm | LinuxCNC motor − commanded mm | difference mm |\n\
         |---|---|---|---|---|---|---|\n",
    );
    let mut up_down: f64 = 0.0;
    for (k, r) in records.iter().enumerate().filter(|(k, _)| k % 3 == 2) {
        let up = (k / 3) % 2 == 0;
        let mut trims = Vec::new();
        for (c, (joint, _, kind)) in files.iter().enumerate() {
            let commanded = r.joints[*joint];
            let target = poses[k][*joint];
            assert!(
                (commanded - target).abs() < 1e-9,
                "joint {joint} at {commanded}, not {target}"
            );
            let expected = crate::export::linuxcnc_trim(&tables[c], target, up);
            let other = crate::export::linuxcnc_trim(&tables[c], target, !up);
            trims.push((expected - other).abs());
            let got = r.motor[c] - commanded;
            let d = (got - expected).abs();
            worst = worst.max(d);
            if d > TOLERANCE {
                failures.push(format!(
                    "joint {joint} at {target} from {}: motor − commanded {got}, the file says {expected}",
                    if up { "below" } else { "above" }
                ));
            }
            writeln!(
                table,
                "| {joint} | {kind} | {target} | {} | {expected:.9} | {got:.9} | {d:.1e} |",
                if up { "from below" } else { "from above" }
            )
            .unwrap();
        }
        up_down = up_down.max(trims[0]);
    }
    println!(
        "{table}\nlargest difference {worst:e} mm ({:.1} s)",
        started.elapsed().as_secs_f64()
    );
    // X's REVERSAL makes the two directions differ by micrometres: the test sees
    // which column LinuxCNC used.
    assert!(
        up_down > 1e-3,
        "X's forward and reverse trims differ by only {up_down} mm at the targets"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
