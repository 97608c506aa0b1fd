use std::path::Path;

use crate::{CoreError, Quat, Vec3};

/// Columns that only a simulation can know: the field without motors, the motor-caused
/// disturbance and the noise standard deviation at each sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GroundTruth {
    /// `true_field_*_ut`: what the sensor would read with the motors off and no noise (eq. 8's m,
    /// including the sensor's own hard and soft iron), microtesla.
    pub field_ut: Vec<Vec3>,
    /// `true_dist_*_ut`: the non-zero-mean disturbance caused by running the motors (eq. 8's dmag).
    pub dist_ut: Vec<Vec3>,
    /// `true_sd_*_ut`: standard deviation of the zero-mean noise mu + eta at that sample.
    pub sd_ut: Vec<Vec3>,
}

/// Accelerometer and gyroscope columns.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuColumns {
    /// `acc_{x,y,z}_mps2`: specific force in the body frame, m/s^2.
    pub acc_mps2: Vec<Vec3>,
    /// `gyr_{x,y,z}_rps`: angular rate in the body frame, rad/s.
    pub gyr_rps: Vec<Vec3>,
}

/// The recording column of the autopilot's own throttle, 0..1: the thrust demand its power
/// compensation multiplies ([`Recording::autopilot_throttle`]).
pub const AUTOPILOT_THROTTLE: &str = "autopilot_throttle";

/// A row counts as motors-off when every command is at most this.
pub const OFF_COMMAND: f64 = 1e-6;

/// Optional columns, what names a user may have given them, and what they hold.
type Lookalike = (&'static str, fn(&str) -> bool, &'static str);

/// The optional columns a user may have logged under another name: an extra column whose
/// name, in lower case without `_`, `-`, `.` and spaces, looks like one of these.
const LOOKALIKES: [Lookalike; 4] = [
    (
        "bat_v",
        |n| {
            let n = squeezed(n);
            n.contains("volt")
                || ["vbat", "batv", "battv", "batteryv", "batmv"]
                    .iter()
                    .any(|p| n.starts_with(p))
        },
        "the supply voltage in volts",
    ),
    (
        "bat_a",
        |n| {
            let n = squeezed(n);
            n.contains("current")
                || ["ibat", "bata", "batta", "batterya", "batma", "amp", "curr"]
                    .iter()
                    .any(|p| n.starts_with(p))
        },
        "the supply current in amperes",
    ),
    (
        "temp_c",
        |n| squeezed(n).contains("temp"),
        "the board temperature in °C",
    ),
    (
        "att_qw",
        |n| {
            let n = squeezed(n);
            n.starts_with("att")
                || n.starts_with("quat")
                || ["q0", "q1", "q2", "q3", "qw", "qx", "qy", "qz"].contains(&n.as_str())
        },
        "the attitude as the quaternion att_qw, att_qx, att_qy, att_qz",
    ),
];

/// `name` in lower case without `_`, `-`, `.` and spaces.
fn squeezed(name: &str) -> String {
    name.chars()
        .filter(|c| !matches!(c, '_' | '-' | '.' | ' '))
        .flat_map(char::to_lowercase)
        .collect()
}

/// One magnetometer sample per row, with what was commanded and measured alongside it.
///
/// Columns are stored column-major. All vectors have [`Recording::len`] entries; use
/// [`Recording::check`] after building one by hand.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// `t_s`: sample time, seconds, strictly increasing.
    pub t_s: Vec<f64>,
    /// Motor commands `thr_1 .. thr_N` in 0..1, `thr[motor][row]`. A recording read from a
    /// single `thr` column has one entry here and [`Recording::overall_only`] set.
    pub thr: Vec<Vec<f64>>,
    /// The recording carried only the overall throttle (`thr`), not per-motor commands.
    pub overall_only: bool,
    /// `mag_{x,y,z}_ut`: measured field in the body frame, microtesla.
    pub mag_ut: Vec<Vec3>,
    /// `bat_v`: supply voltage, volts.
    pub bat_v: Option<Vec<f64>>,
    /// `bat_a`: supply current, amperes.
    pub bat_a: Option<Vec<f64>>,
    /// `temp_c`: board temperature, degrees Celsius.
    pub temp_c: Option<Vec<f64>>,
    /// Accelerometer and gyroscope, when recorded.
    pub imu: Option<ImuColumns>,
    /// `att_q{w,x,y,z}`: attitude, the rotation from the body frame to north-east-down (PX4's
    /// `vehicle_attitude.q`), when recorded. Flight logs need it to take the Earth field out.
    pub attitude: Option<Vec<Quat>>,
    /// Ground truth, present in simulated recordings.
    pub truth: Option<GroundTruth>,
    /// Any other columns, kept verbatim (name, cells) so that tools pass them through.
    pub extra: Vec<(String, Vec<String>)>,
}

impl Recording {
    /// Number of rows (magnetometer samples).
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when the recording has no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Whether every motor command of `row` is off (at most [`OFF_COMMAND`]).
    pub fn motors_off(&self, row: usize) -> bool {
        self.thr.iter().all(|m| m[row] <= OFF_COMMAND)
    }

    /// Number of motor command columns (1 when only the overall throttle was recorded).
    pub fn motor_count(&self) -> usize {
        self.thr.len()
    }

    /// Overall throttle at a row: the mean of the motor commands, in 0..1.
    ///
    /// The paper defines the overall throttle as the sum of the motor commands (eq. 7) and then
    /// normalizes it to 0..1; the mean is that normalized sum.
    pub fn overall_throttle(&self, row: usize) -> f64 {
        let n = self.thr.len().max(1) as f64;
        self.thr.iter().map(|m| m[row]).sum::<f64>() / n
    }

    /// Overall throttle for every row.
    pub fn overall_throttle_column(&self) -> Vec<f64> {
        (0..self.len()).map(|r| self.overall_throttle(r)).collect()
    }

    /// The cells of the extra column `name` (one of [`Recording::extra`], which tools pass
    /// through), if the recording has it.
    pub fn extra_column(&self, name: &str) -> Option<&[String]> {
        self.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, cells)| cells.as_slice())
    }

    /// The one value the extra column `name` holds in every row (`import` writes a log's
    /// properties so, e.g. the magnetometer's parameter set), with the first row (from 0) that
    /// holds it: None where the column is absent or every cell empty. A cell that does not
    /// parse, or holds another value than the rows before it, is an error naming its row;
    /// `why_one` says why the column holds one value (a recording is of one magnetometer).
    pub fn one_value_column<T>(
        &self,
        name: &str,
        path: &Path,
        why_one: &str,
    ) -> Result<Option<(usize, T)>, CoreError>
    where
        T: std::str::FromStr<Err = String> + PartialEq + std::fmt::Display,
    {
        let Some(cells) = self.extra_column(name) else {
            return Ok(None);
        };
        let mut found: Option<(usize, T)> = None;
        for (row, cell) in cells.iter().enumerate() {
            let cell = cell.trim();
            if cell.is_empty() {
                continue;
            }
            let bad = |expected: String| CoreError::BadCell {
                path: path.to_path_buf(),
                row: row + 1,
                column: name.into(),
                found: cell.into(),
                expected,
            };
            let value: T = cell.parse().map_err(bad)?;
            match &found {
                Some((first, v)) if *v != value => {
                    return Err(bad(format!(
                        "the value of row {} ({v}): {why_one}",
                        first + 1
                    )));
                }
                Some(_) => {}
                None => found = Some((row, value)),
            }
        }
        Ok(found)
    }

    /// The recording with `value` written in every row of the extra column `name`
    /// (replacing any), or the column removed where `value` is None.
    pub fn set_one_value_column(&mut self, name: &str, value: Option<impl std::fmt::Display>) {
        self.extra.retain(|(n, _)| n != name);
        if let Some(value) = value {
            self.extra
                .push((name.into(), vec![value.to_string(); self.len()]));
        }
    }

    /// The autopilot's own throttle at every row ([`AUTOPILOT_THROTTLE`], which `import`
    /// writes): the collective thrust demand an autopilot's throttle compensation multiplies,
    /// which its thrust curve maps to the motor commands. None where the recording has no such
    /// column; an error naming the row where a cell is not a throttle in 0..1.
    pub fn autopilot_throttle(&self, path: &Path) -> Result<Option<Vec<f64>>, CoreError> {
        let Some(cells) = self.extra_column(AUTOPILOT_THROTTLE) else {
            return Ok(None);
        };
        cells
            .iter()
            .enumerate()
            .map(|(row, cell)| {
                cell.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| (0.0..=1.0).contains(v))
                    .ok_or_else(|| CoreError::BadCell {
                        path: path.to_path_buf(),
                        row: row + 1,
                        column: AUTOPILOT_THROTTLE.into(),
                        found: cell.clone(),
                        expected: "the autopilot's throttle, a number in 0..1".into(),
                    })
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    /// Motor commands of one row, one entry per motor.
    pub fn motor_commands(&self, row: usize) -> Vec<f64> {
        self.thr.iter().map(|m| m[row]).collect()
    }

    /// Why the magnetometer does not respond, where an axis reads the same value (within
    /// 1e-9 µT) on every one of two or more rows: a stuck or disconnected sensor (often at
    /// zero). Its residual has no noise at all, which any model fits and any effect
    /// "explains", so the commands that fit it refuse it with this. None for fewer than two
    /// rows, or where every axis moves.
    pub fn unresponsive_magnetometer(&self) -> Option<String> {
        let first = self.mag_ut.first().filter(|_| self.len() >= 2)?;
        let a = (0..3).find(|&a| self.mag_ut.iter().all(|m| (m[a] - first[a]).abs() <= 1e-9))?;
        Some(format!(
            "the magnetometer does not respond: mag_{}_ut reads {:.4} µT in every one of the {} rows; expected readings that change with the commands and the noise",
            crate::AXES[a],
            first[a],
            self.len()
        ))
    }

    /// Doubts about what the recording's columns hold, one sentence each, for a tool to warn
    /// of: the units of `t_s` and `mag_*_ut`, then columns that are not read but look meant
    /// to be. Rows more than 2 s apart (median), slower than any motor or field change this
    /// tool models, as times in milliseconds or microseconds would be; a field whose median
    /// magnitude is beyond a factor 5 of the Earth's (22 to 67 µT at the surface), as
    /// readings in gauss, milligauss or nanotesla would be; an extra column named like
    /// `bat_v`, `bat_a`, `temp_c` or the attitude where that column is absent
    /// ([`Recording::unread_column_doubts`]); a logged supply voltage that drops out while
    /// the motors are commanded ([`Recording::supply_dropout_doubts`]) and a logged
    /// temperature that steps faster than a board warms
    /// ([`Recording::temperature_jump_doubts`]); on a stand, a field that leaves and comes
    /// back within one row ([`Recording::magnetometer_spike_doubts`]). Warnings, not errors:
    /// a stand may cancel the Earth's field, a log may be slow, a column may hold something
    /// else, and a supply may fail. Empty where none is seen.
    pub fn doubts(&self) -> Vec<String> {
        let mut doubts = self.unit_doubts();
        doubts.extend(self.unread_column_doubts());
        doubts.extend(self.supply_dropout_doubts());
        doubts.extend(self.temperature_jump_doubts());
        doubts.extend(self.magnetometer_spike_doubts());
        doubts
    }

    /// The doubt of [`Recording::doubts`] about `mag_*_ut` on a stand (no attitude logged): a
    /// single row that leaves both its neighbours by more than 10 µT and 20 times the axis's
    /// median step, in the same direction, while the neighbours agree within half that. The
    /// field of a restrained vehicle follows its currents through spin-up lags and does not
    /// come back within one row; a sensor's read error does. Least squares weighs such a row
    /// by its square: on the independent generator's control, four rows of +300 µT in 25,000
    /// raised the diagnosis's held-out RMSE on x from 0.207 to 0.232 µT. (In flight the
    /// Earth's field turns with the vehicle, and a fast turn can look like this: a flight is
    /// not doubted.)
    pub fn magnetometer_spike_doubts(&self) -> Vec<String> {
        if self.attitude.is_some() || self.len() < 3 {
            return Vec::new();
        }
        let mut spikes: Vec<(usize, usize)> = Vec::new();
        for axis in 0..3 {
            let m: Vec<f64> = self.mag_ut.iter().map(|v| v[axis]).collect();
            let mut steps: Vec<f64> = m.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
            let Some(median_step) = upper_median(&mut steps) else {
                continue;
            };
            let beyond = SPIKE_FLOOR_UT.max(20.0 * median_step);
            spikes.extend(
                m.windows(3)
                    .enumerate()
                    .filter(|(_, w)| {
                        let (up, down) = (w[1] - w[0], w[1] - w[2]);
                        up.abs() > beyond
                            && down.abs() > beyond
                            && up * down > 0.0
                            && (w[2] - w[0]).abs() < 0.5 * beyond
                    })
                    .map(|(r, _)| (r + 1, axis)),
            );
        }
        spikes.sort_unstable();
        let Some(&(first, axis)) = spikes.first() else {
            return Vec::new();
        };
        let m = |r: usize| self.mag_ut[r][axis];
        vec![format!(
            "the field leaves both neighbouring rows and comes back on {} row(s), the first at \
             data row {} (t_s = {:.3} s, mag_{}_ut {:.2} -> {:.2} -> {:.2} µT), where a stand's \
             field follows its currents: a sensor's read error? Each such row weighs on every \
             fit by its square; leave those rows out",
            spikes.len(),
            first + 1,
            self.t_s[first],
            crate::AXES[axis],
            m(first - 1),
            m(first),
            m(first + 1)
        )]
    }

    /// The doubt of [`Recording::doubts`] about `temp_c`: steps between consecutive rows of
    /// more than 5 °C at more than 1 °C/s. A board near motor wiring warms by degrees a
    /// minute, and no sensor on it moves that fast; a logger's dropout (0 or -40 °C for an
    /// unread sensor) or another column's value does. A diagnosis with `temp_c` takes the
    /// board's heating from it, so each step is a step of the modelled field.
    pub fn temperature_jump_doubts(&self) -> Vec<String> {
        let Some(temp_c) = self.temp_c.as_deref() else {
            return Vec::new();
        };
        let jumps: Vec<usize> = (1..self.len())
            .filter(|&r| {
                let step_c = (temp_c[r] - temp_c[r - 1]).abs();
                let dt_s = self.t_s[r] - self.t_s[r - 1];
                step_c > TEMPERATURE_JUMP_C && step_c > TEMPERATURE_RATE_C_PER_S * dt_s
            })
            .collect();
        let Some(&first) = jumps.first() else {
            return Vec::new();
        };
        vec![format!(
            "temp_c steps by more than {TEMPERATURE_JUMP_C} °C between consecutive rows {} \
             time(s), the first into data row {} (t_s = {:.3} s: {:.2} -> {:.2} °C), faster \
             than a board warms: a logger's dropout? The board's heating is taken from temp_c; \
             fill those rows with the temperature around them, or leave temp_c out",
            jumps.len(),
            first + 1,
            self.t_s[first],
            temp_c[first - 1],
            temp_c[first]
        )]
    }

    /// The doubt of [`Recording::doubts`] about `bat_v`: rows whose motors are commanded (not
    /// [`Recording::motors_off`]) and whose logged voltage is below half its median over such
    /// rows. No pack or bench runs
    /// its motors there (a LiPo from full to empty spans 4.2 to 3.3 V a cell, and sags a few
    /// tenths under load), but a logger that writes 0 before its sensor answers, or a
    /// dropped sample, does; a replay that follows the logged voltage (a battery followed
    /// through `bat_v`, a physics fit) drives its motors with it, so each such row stops them
    /// in the model while the recorded field shows them running.
    pub fn supply_dropout_doubts(&self) -> Vec<String> {
        let Some(bat_v) = self.bat_v.as_deref() else {
            return Vec::new();
        };
        let commanded: Vec<usize> = (0..self.len()).filter(|&r| !self.motors_off(r)).collect();
        let mut levels: Vec<f64> = commanded.iter().map(|&r| bat_v[r]).collect();
        let Some(median_v) = upper_median(&mut levels).filter(|&m| m > 0.0) else {
            return Vec::new();
        };
        let low: Vec<usize> = commanded
            .into_iter()
            .filter(|&r| bat_v[r] < 0.5 * median_v)
            .collect();
        let Some(&first) = low.first() else {
            return Vec::new();
        };
        vec![format!(
            "bat_v is below half its median ({median_v:.3} V) on {} of the rows whose motors are \
             commanded, the first data row {} (t_s = {:.3} s, {:.3} V): a logger's dropout? \
             Where the logged voltage drives the replayed motors, it stops them at those rows; \
             fill them with the voltage around them, or leave bat_v out",
            low.len(),
            first + 1,
            self.t_s[first],
            bat_v[first]
        )]
    }

    /// The doubts of [`Recording::doubts`] about the units of `t_s` and `mag_*_ut`.
    fn unit_doubts(&self) -> Vec<String> {
        let mut doubts = Vec::new();
        let interval_s = self.typical_interval_s();
        if interval_s > 2.0 {
            doubts.push(format!(
                "rows are {interval_s:.4} s apart (median): t_s is in seconds, and times in \
                 milliseconds or microseconds would look like this"
            ));
        }
        let mut norms: Vec<f64> = self.mag_ut.iter().map(|m| m.norm()).collect();
        if let Some(median_ut) = upper_median(&mut norms)
            .filter(|m| self.len() >= 2 && !(22.0 / 5.0..=67.0 * 5.0).contains(m))
        {
            doubts.push(format!(
                "the field's median magnitude is {median_ut:.4} µT, where the Earth's is 22 to 67 \
                 µT: mag_*_ut is in microtesla (1 gauss = 100 µT, 1 mG = 0.1 µT, 1 nT = 0.001 \
                 µT), unless the stand cancels or adds a field"
            ));
        }
        doubts
    }

    /// The doubts of [`Recording::doubts`] about extra columns: one whose name is a column's
    /// this tool reads in other letter case, or, where `bat_v`, `bat_a`, `temp_c` or the
    /// attitude is absent, one named as a supply voltage, current, temperature or quaternion
    /// would be (`vbat`, `Voltage`, `current_a`, `temp`, `q0`). Such a column is kept as
    /// extra and not used: a diagnosis without `bat_v` calibrates the battery's sag, and
    /// one without `temp_c` takes heating from the power, which a user who logged them
    /// would not expect.
    pub fn unread_column_doubts(&self) -> Vec<String> {
        // The columns the recording reads, as its writer names them.
        let read = crate::recording_csv::header(self);
        let mut doubts = Vec::new();
        for (name, _) in &self.extra {
            let lower = name.to_ascii_lowercase();
            let read_in_other_case = lower != *name
                && crate::recording_csv::READ_COLUMNS.iter().any(|r| {
                    // A name ending in `_` is a prefix of columns read.
                    if r.ends_with('_') {
                        lower.starts_with(r)
                    } else {
                        lower == *r
                    }
                });
            if read_in_other_case {
                doubts.push(format!(
                    "column `{name}` is not read: column names are lower case, as `{lower}`"
                ));
                continue;
            }
            let meant = LOOKALIKES
                .iter()
                .find(|(_, looks_like, _)| looks_like(name));
            if let Some((column, _, what)) = meant.filter(|(c, _, _)| !read.iter().any(|r| r == c))
            {
                doubts.push(format!(
                    "column `{name}` is not read: magstand reads {what} as `{column}`; rename it \
                     if that is what it holds"
                ));
            }
        }
        doubts
    }

    /// Typical sample interval in seconds: the median of the intervals between rows (0 for
    /// fewer than two rows). Unlike the mean it ignores the long gaps of a log that holds
    /// several flights, which would make a 10 Hz log look like a 1 Hz one.
    pub fn typical_interval_s(&self) -> f64 {
        typical_interval_s(&self.t_s)
    }

    /// Keeps only the rows whose index satisfies `keep`, in every column.
    pub fn select_rows(&self, keep: impl Fn(usize) -> bool) -> Recording {
        let rows: Vec<usize> = (0..self.len()).filter(|&r| keep(r)).collect();
        let pick = |v: &Vec<f64>| rows.iter().map(|&r| v[r]).collect::<Vec<_>>();
        let pick3 = |v: &Vec<Vec3>| rows.iter().map(|&r| v[r]).collect::<Vec<_>>();
        Recording {
            t_s: pick(&self.t_s),
            thr: self.thr.iter().map(pick).collect(),
            overall_only: self.overall_only,
            mag_ut: pick3(&self.mag_ut),
            bat_v: self.bat_v.as_ref().map(pick),
            bat_a: self.bat_a.as_ref().map(pick),
            temp_c: self.temp_c.as_ref().map(pick),
            attitude: self
                .attitude
                .as_ref()
                .map(|q| rows.iter().map(|&r| q[r]).collect()),
            imu: self.imu.as_ref().map(|i| ImuColumns {
                acc_mps2: pick3(&i.acc_mps2),
                gyr_rps: pick3(&i.gyr_rps),
            }),
            truth: self.truth.as_ref().map(|g| GroundTruth {
                field_ut: pick3(&g.field_ut),
                dist_ut: pick3(&g.dist_ut),
                sd_ut: pick3(&g.sd_ut),
            }),
            extra: self
                .extra
                .iter()
                .map(|(n, c)| (n.clone(), rows.iter().map(|&r| c[r].clone()).collect()))
                .collect(),
        }
    }

    /// Checks that every column has one value per row, values are finite, motor commands lie in
    /// 0..1 and time strictly increases. Row numbers in errors are 1-based.
    pub fn check(&self) -> Result<(), CoreError> {
        let n = self.len();
        let len_err = |column: &str, found: usize| CoreError::ColumnLength {
            column: column.to_string(),
            found,
            expected: n,
        };
        if self.thr.is_empty() {
            return Err(len_err("thr_1", 0));
        }
        for (i, m) in self.thr.iter().enumerate() {
            if m.len() != n {
                return Err(len_err(&format!("thr_{}", i + 1), m.len()));
            }
        }
        if self.mag_ut.len() != n {
            return Err(len_err("mag_*_ut", self.mag_ut.len()));
        }
        for (name, col) in [
            ("bat_v", &self.bat_v),
            ("bat_a", &self.bat_a),
            ("temp_c", &self.temp_c),
        ] {
            if let Some(c) = col
                && c.len() != n
            {
                return Err(len_err(name, c.len()));
            }
        }
        if let Some(i) = &self.imu {
            if i.acc_mps2.len() != n {
                return Err(len_err("acc_*_mps2", i.acc_mps2.len()));
            }
            if i.gyr_rps.len() != n {
                return Err(len_err("gyr_*_rps", i.gyr_rps.len()));
            }
        }
        if let Some(q) = &self.attitude
            && q.len() != n
        {
            return Err(len_err("att_q*", q.len()));
        }
        if let Some(g) = &self.truth {
            for (name, c) in [
                ("true_field_*_ut", &g.field_ut),
                ("true_dist_*_ut", &g.dist_ut),
                ("true_sd_*_ut", &g.sd_ut),
            ] {
                if c.len() != n {
                    return Err(len_err(name, c.len()));
                }
            }
        }
        for (name, c) in &self.extra {
            if c.len() != n {
                return Err(len_err(name, c.len()));
            }
        }
        Ok(())
    }
}

/// Typical interval of sample times `t_s`: the median of the intervals (0 for fewer than two
/// samples).
pub fn typical_interval_s(t_s: &[f64]) -> f64 {
    let mut d: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    upper_median(&mut d).unwrap_or(0.0)
}

/// The least jump of a single row of `mag_*_ut` away from both its neighbours and back that
/// is doubted, µT: a fifth of the Earth's weakest field, and far beyond a magnetometer's noise.
const SPIKE_FLOOR_UT: f64 = 10.0;

/// A step of `temp_c` between two rows beyond which it is doubted, °C (with
/// [`TEMPERATURE_RATE_C_PER_S`]).
const TEMPERATURE_JUMP_C: f64 = 5.0;

/// A rate of `temp_c` beyond which a step of more than [`TEMPERATURE_JUMP_C`] is doubted, °C/s:
/// a tenfold margin over a board beside motor wiring warming by degrees a minute.
const TEMPERATURE_RATE_C_PER_S: f64 = 1.0;

/// The median of `values` (the upper of the two middle ones for an even count), reordering
/// them; None for none.
fn upper_median(values: &mut [f64]) -> Option<f64> {
    let mid = values.len() / 2;
    (!values.is_empty()).then(|| *values.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// An interval longer than this many typical intervals is a gap (as `magstand import` reports
/// them): a log holding several flights, or a logger that stopped.
pub const GAP_INTERVALS: f64 = 5.0;

/// The rows of `t_s` that follow a gap (an interval longer than [`GAP_INTERVALS`] typical
/// intervals): each starts a new stretch of continuous data.
pub fn rows_after_gaps(t_s: &[f64]) -> Vec<usize> {
    let gap_s = GAP_INTERVALS * typical_interval_s(t_s);
    (1..t_s.len())
        .filter(|&r| t_s[r] - t_s[r - 1] > gap_s)
        .collect()
}
