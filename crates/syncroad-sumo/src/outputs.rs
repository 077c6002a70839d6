//! Every file SUMO writes for a run lands inside the run's folder. The user's additional files
//! name output files of their own (a detector's `file`, a calibrator's `output`, a timed
//! event's `dest`), which SUMO resolves against the additional file's folder or takes as
//! absolute: a run would replace whatever is there, and the points of a sweep would all write
//! the same file. So a user additional file with outputs is given to SUMO as a copy in the
//! run's work folder whose output attributes point into `outputs/` there (one file per
//! output name and run), and whose relative inputs point back at the original's folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::prepare_error::PrepareError;

/// Where a run's redirected outputs go, inside its work folder.
pub const OUTPUTS_DIR: &str = "outputs";

/// `(element, attribute)` pairs that name an output file.
const OUTPUTS: [(&str, &str); 17] = [
    ("inductionLoop", "file"),
    ("e1Detector", "file"),
    ("instantInductionLoop", "file"),
    ("laneAreaDetector", "file"),
    ("e2Detector", "file"),
    ("multiLaneAreaDetector", "file"),
    ("entryExitDetector", "file"),
    ("e3Detector", "file"),
    ("edgeData", "file"),
    ("laneData", "file"),
    ("routeProbe", "file"),
    ("vTypeProbe", "file"),
    ("calibrator", "output"),
    ("rerouter", "output"),
    ("variableSpeedSign", "output"),
    ("timedEvent", "dest"),
    ("overheadWireSegment", "output"),
];

/// `(element, attribute)` pairs that name an input file, resolved against the original's
/// folder in a copy.
const INPUTS: [(&str, &str); 4] = [
    ("include", "href"),
    ("rerouter", "file"),
    ("poi", "imgFile"),
    ("poly", "imgFile"),
];

/// Values that name no file.
fn is_special(v: &str) -> bool {
    matches!(v, "" | "NUL" | "/dev/null" | "nul")
}

/// A file name safe in a folder: the last component of `v` with other characters than
/// letters, digits and `._-` replaced.
fn safe_name(v: &str) -> String {
    let last = v.rsplit(['/', '\\']).next().unwrap_or(v);
    let s: String = last
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "output".into()
    } else {
        s
    }
}

/// The additional files to give SUMO: each of `files` as it is when it names no output,
/// else its copy `work_dir/additional-K.add.xml` with outputs under `work_dir/outputs/`
/// (written when `write`). A file too large to read here is given as it is.
pub(crate) fn redirect(
    files: &[PathBuf],
    work_dir: &Path,
    write: bool,
) -> Result<Vec<PathBuf>, PrepareError> {
    let mut out = Vec::with_capacity(files.len());
    for (index, path) in files.iter().enumerate() {
        let bad = |reason: String| PrepareError::UserFile {
            field: "sumo.additional",
            index,
            path: path.clone(),
            reason,
        };
        let Ok(Some(text)) = crate::input_file::read_text(path, Some(64 << 20)) else {
            out.push(path.clone());
            continue;
        };
        let Ok(doc) = roxmltree::Document::parse(&text) else {
            out.push(path.clone());
            continue;
        };
        let base = path.parent().unwrap_or(Path::new("."));
        let base = std::path::absolute(base).unwrap_or_else(|_| base.to_path_buf());
        let dir = std::path::absolute(work_dir.join(OUTPUTS_DIR))
            .unwrap_or_else(|_| work_dir.join(OUTPUTS_DIR));
        // Replacements (byte range of an attribute value → new value), and one output file
        // per output name.
        let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
        let mut names: BTreeMap<String, String> = BTreeMap::new();
        for n in doc.descendants().filter(|n| n.is_element()) {
            let tag = n.tag_name().name();
            for a in n.attributes() {
                let is_output = OUTPUTS.contains(&(tag, a.name()));
                let is_input = INPUTS.contains(&(tag, a.name()));
                let v = a.value();
                if is_output && !is_special(v) {
                    let k = names.len();
                    let name = names
                        .entry(v.to_string())
                        .or_insert_with(|| format!("a{index}-{k}-{}", safe_name(v)))
                        .clone();
                    edits.push((a.range_value(), dir.join(name).display().to_string()));
                } else if is_input && !v.is_empty() && Path::new(v).is_relative() {
                    edits.push((a.range_value(), base.join(v).display().to_string()));
                }
            }
        }
        if names.is_empty() {
            out.push(path.clone());
            continue;
        }
        edits.sort_by_key(|e| std::cmp::Reverse(e.0.start));
        let mut copy = text.clone();
        for (range, value) in edits {
            copy.replace_range(range, &quick_xml::escape::escape(value.as_str()));
        }
        let target = work_dir.join(format!("additional-{index}.add.xml"));
        if write {
            std::fs::create_dir_all(&dir)
                .and_then(|()| std::fs::write(&target, copy))
                .map_err(|e| {
                    bad(format!(
                        "cannot write its copy with outputs in the run's folder ({e})"
                    ))
                })?;
        }
        out.push(target);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_move_into_the_run_and_inputs_keep_pointing_at_the_original_folder() {
        let dir = tempfile::tempdir().unwrap();
        let user = dir.path().join("user");
        std::fs::create_dir_all(&user).unwrap();
        let add = user.join("det.add.xml");
        std::fs::write(
            &add,
            r#"<additional><inductionLoop id="a" lane="l" pos="1" file="/abs/victim.txt"/><inductionLoop id="b" lane="l" pos="2" file="/abs/victim.txt"/><e2Detector id="c" lane="l" file="rel &amp; out.xml"/><include href="more.add.xml"/><edgeData id="m" file="NUL"/></additional>"#,
        )
        .unwrap();
        let plain = user.join("plain.add.xml");
        std::fs::write(&plain, "<additional><vType id=\"t\"/></additional>").unwrap();
        let work = dir.path().join("run/sumo");
        let files = redirect(&[add.clone(), plain.clone()], &work, true).unwrap();
        assert_eq!(files[1], plain, "a file without outputs is given as it is");
        let text = std::fs::read_to_string(&files[0]).unwrap();
        let doc = roxmltree::Document::parse(&text).unwrap();
        let attr = |id: &str, name: &str| {
            doc.descendants()
                .find(|n| n.attribute("id") == Some(id))
                .and_then(|n| n.attribute(name))
                .unwrap()
                .to_string()
        };
        let out = std::path::absolute(work.join("outputs")).unwrap();
        // Two detectors of one file keep writing one file, now the run's.
        assert_eq!(attr("a", "file"), attr("b", "file"));
        assert!(
            Path::new(&attr("a", "file")).starts_with(&out),
            "{}",
            attr("a", "file")
        );
        assert!(Path::new(&attr("c", "file")).starts_with(&out));
        assert!(attr("c", "file").ends_with("rel___out.xml"));
        assert_eq!(attr("m", "file"), "NUL");
        let include = doc
            .descendants()
            .find(|n| n.has_tag_name("include"))
            .unwrap()
            .attribute("href")
            .unwrap()
            .to_string();
        assert_eq!(
            Path::new(&include),
            std::path::absolute(user.join("more.add.xml")).unwrap()
        );
        assert!(out.is_dir());
    }
}
