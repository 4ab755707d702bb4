//! Typing the landmarks at a prompt, in LPS mm (`x y z`) or in voxel indices (`v i j k`).
//! Each answer is echoed with its position in both systems and the intensity there; a bad or
//! out-of-image answer is explained and asked again. With landmarks proposed from the image,
//! each question offers its proposal: an empty answer (Enter) accepts it. Works on a terminal
//! (dialoguer) and line by line from a pipe, for scripts and tests.

use std::io::{BufRead, Read, Write};

use nalgebra::{Point3, Vector3};

use super::{LandmarkError, LandmarkName, Landmarks};
use crate::image::Sampler;

/// Longest answer line read from a non-terminal input [bytes].
const MAX_ANSWER_BYTES: u64 = 4096;

/// Where the answers come from.
pub enum PromptInput<'a> {
    /// An interactive terminal (line editing through dialoguer).
    Terminal,
    /// Lines from a reader (a pipe); prompts and echoes go to `echo`.
    Lines {
        input: &'a mut dyn BufRead,
        echo: &'a mut dyn Write,
    },
}

/// Parses one answer into a world (LPS mm) position.
fn parse_answer(text: &str, sampler: &Sampler) -> Result<Point3<f64>, String> {
    let lower = text.trim().to_ascii_lowercase();
    let (voxel, rest) = match lower
        .strip_prefix("voxel")
        .or_else(|| lower.strip_prefix('v'))
    {
        Some(rest) => (true, rest.to_string()),
        None => (false, lower.clone()),
    };
    let nums: Result<Vec<f64>, _> = rest
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(str::parse::<f64>)
        .collect();
    let nums = nums.map_err(|_| {
        format!("{text:?}: expected three numbers, 'x y z' (LPS mm) or 'v i j k' (voxel indices)")
    })?;
    if nums.len() != 3 || nums.iter().any(|v| !v.is_finite()) {
        return Err(format!("{text:?}: expected exactly three finite numbers"));
    }
    let v = Vector3::new(nums[0], nums[1], nums[2]);
    let p = if voxel {
        Point3::from(sampler.volume().index_to_world(v))
    } else {
        Point3::from(v)
    };
    if !sampler.contains(&p) {
        let ijk = sampler.index_of(&p);
        return Err(format!(
            "({:.2}, {:.2}, {:.2}) mm LPS is outside the image (voxel {:.1}, {:.1}, {:.1}; dims {:?})",
            p.x,
            p.y,
            p.z,
            ijk.x,
            ijk.y,
            ijk.z,
            sampler.volume().dims
        ));
    }
    Ok(p)
}

fn describe(name: LandmarkName, p: &Point3<f64>, sampler: &Sampler) -> String {
    let ijk = sampler.index_of(p);
    let value = sampler
        .sample(p)
        .map_or("n/a".to_string(), |v| format!("{v:.0}"));
    format!(
        "{}: ({:.3}, {:.3}, {:.3}) mm LPS = voxel ({:.2}, {:.2}, {:.2}), intensity {value}",
        name.key(),
        p.x,
        p.y,
        p.z,
        ijk.x,
        ijk.y,
        ijk.z
    )
}

/// Asks for the three landmarks in turn; `proposed`, when given, is each answer's default.
pub fn prompt_landmarks(
    mut input: PromptInput,
    sampler: &Sampler,
    proposed: Option<&Landmarks>,
) -> Result<Landmarks, LandmarkError> {
    let mut points = Vec::with_capacity(3);
    for name in LandmarkName::ALL {
        let default = proposed.map(|l| {
            let p = l.get(name);
            format!("{:.3} {:.3} {:.3}", p.x, p.y, p.z)
        });
        let question = match &default {
            None => format!("{} ('x y z' in LPS mm, or 'v i j k' in voxels)", name.key()),
            Some(d) => format!(
                "{} ('x y z' in LPS mm, or 'v i j k' in voxels; Enter accepts the proposal {d})",
                name.key()
            ),
        };
        let p = match &mut input {
            PromptInput::Terminal => {
                let mut prompt = dialoguer::Input::new()
                    .with_prompt(&question)
                    .validate_with(|s: &String| parse_answer(s, sampler).map(|_| ()));
                if let Some(d) = &default {
                    prompt = prompt.default(d.clone()).show_default(false);
                }
                let answer: String = prompt
                    .interact_text()
                    .map_err(|_| LandmarkError::PromptEnded)?;
                let p = parse_answer(&answer, sampler).map_err(|_| LandmarkError::PromptEnded)?;
                eprintln!("  {}", describe(name, &p, sampler));
                p
            }
            PromptInput::Lines { input, echo } => loop {
                let _ = write!(echo, "{question}: ");
                let _ = echo.flush();
                let mut line = String::new();
                // an answer is one short line: never read further (`< /dev/zero` grew forever)
                let read = (&mut **input)
                    .take(MAX_ANSWER_BYTES)
                    .read_line(&mut line)
                    .map_err(|_| LandmarkError::PromptEnded)?;
                if read == 0 || (read as u64 == MAX_ANSWER_BYTES && !line.ends_with('\n')) {
                    let _ = writeln!(echo);
                    return Err(LandmarkError::PromptEnded);
                }
                if line.trim().is_empty() {
                    match &default {
                        Some(d) => line = d.clone(),
                        None => {
                            let _ = writeln!(echo, "(empty answer)");
                            continue;
                        }
                    }
                }
                match parse_answer(&line, sampler) {
                    Ok(p) => {
                        let _ = writeln!(echo, "\n  {}", describe(name, &p, sampler));
                        break p;
                    }
                    Err(msg) => {
                        let _ = writeln!(echo, "\n  {msg}; try again");
                    }
                }
            },
        };
        points.push(p);
    }
    Ok(Landmarks::from_points([points[0], points[1], points[2]]))
}
