//! A SUMO configuration file (`sumo.config`, a `.sumocfg`): its input section, the files a
//! user's own SUMO setup loads.
//!
//! SUMO reads a configuration as `<configuration>` with one element per option, grouped in
//! sections (`<input>`, `<time>`, …) or not, each with its value in `value`; relative paths are
//! resolved against the configuration's folder and file lists are separated by commas. syncroad
//! takes `net-file`, `route-files` and `additional-files` from it and does not pass the file
//! to SUMO (`-c`): the scenario sets the time, the step and the seed, and a configuration's
//! output options would write files outside the run folder, over files syncroad did not
//! create. Every other option is reported as ignored.

use std::path::{Path, PathBuf};

use syncroad_control::scenario::ConfigInputs;

/// Why a configuration cannot be read; each message names `sumo.config` and the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read.
    #[error("sumo.config = {path}: {reason}")]
    Unreadable {
        /// The file.
        path: String,
        /// The system's reason.
        reason: String,
    },
    /// Not XML, or not a SUMO configuration.
    #[error("sumo.config = {path}: {reason}; a SUMO configuration is <configuration> with one element per option, e.g. <input><net-file value=\"my.net.xml\"/></input>")]
    NotAConfiguration {
        /// The file.
        path: String,
        /// What is wrong.
        reason: String,
    },
    /// A file the input section names is not there.
    #[error("sumo.config = {path}: {option} names {file}, which is not there (relative paths are resolved against the configuration's folder, as SUMO does)")]
    Missing {
        /// The configuration.
        path: String,
        /// The option.
        option: String,
        /// The file, resolved.
        file: String,
    },
    /// An option of the input section without a value.
    #[error("sumo.config = {path}: option <{option}> has no value (SUMO reads options as <{option} value=\"…\"/>, a file list separated by commas)")]
    NoValue {
        /// The file.
        path: String,
        /// The option.
        option: String,
    },
}

/// The options syncroad takes, and what SUMO also accepts for them in a configuration.
const NET: [&str; 2] = ["net-file", "n"];
const ROUTES: [&str; 2] = ["route-files", "r"];
const ADDITIONAL: [&str; 2] = ["additional-files", "a"];

/// Reads the input section of the configuration `path`.
pub fn read_config(path: &Path) -> Result<ConfigInputs, ConfigError> {
    let shown = path.display().to_string();
    let text = crate::input_file::read_text(path, None)
        .map_err(|reason| ConfigError::Unreadable {
            path: shown.clone(),
            reason,
        })?
        .unwrap_or_default();
    let doc = roxmltree::Document::parse(&text).map_err(|e| ConfigError::NotAConfiguration {
        path: shown.clone(),
        reason: format!("not XML ({e})"),
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "configuration" {
        return Err(ConfigError::NotAConfiguration {
            path: shown,
            reason: format!("the root element is <{}>", root.tag_name().name()),
        });
    }
    let base = path.parent().unwrap_or(Path::new(""));
    let files = |v: &str| -> Vec<PathBuf> {
        v.split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|s| base.join(s))
            .collect()
    };
    let mut inputs = ConfigInputs::default();
    // Options directly under <configuration> or in one of its sections.
    let options = root.children().filter(|n| n.is_element()).flat_map(|n| {
        if n.attribute("value").is_some() || !n.children().any(|c| c.is_element()) {
            vec![n]
        } else {
            n.children().filter(|c| c.is_element()).collect()
        }
    });
    for o in options {
        let name = o.tag_name().name();
        let value = o.attribute("value");
        if !(NET.contains(&name) || ROUTES.contains(&name) || ADDITIONAL.contains(&name)) {
            inputs.ignored.push(match value {
                Some(v) => format!("{name} = {v}"),
                None => name.to_string(),
            });
            continue;
        }
        let listed = value.map(files).unwrap_or_default();
        if listed.is_empty() {
            return Err(ConfigError::NoValue {
                path: shown,
                option: name.to_string(),
            });
        }
        if let Some(f) = listed.iter().find(|f| !f.exists()) {
            return Err(ConfigError::Missing {
                path: shown,
                option: name.to_string(),
                file: f.display().to_string(),
            });
        }
        if NET.contains(&name) {
            inputs.net = listed.into_iter().next();
        } else if ROUTES.contains(&name) {
            inputs.routes.extend(listed);
        } else {
            inputs.additional.extend(listed);
        }
    }
    Ok(inputs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(d: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
        let p = d.path().join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn the_input_section_is_taken_relative_to_the_file_and_the_rest_is_listed() {
        let d = tempfile::tempdir().unwrap();
        for f in [
            "nets/track.net.xml",
            "a.rou.xml",
            "b.rou.xml",
            "det.add.xml",
        ] {
            write(&d, f, "<x/>");
        }
        let p = write(
            &d,
            "a.sumocfg",
            r#"<?xml version="1.0"?>
<configuration xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
    <input>
        <net-file value="nets/track.net.xml"/>
        <route-files value="a.rou.xml, b.rou.xml"/>
        <additional-files value="ABS"/>
    </input>
    <time><begin value="0"/><step-length value="0.5"/></time>
    <fcd-output value="fcd.xml"/>
</configuration>
"#,
        );
        let dir = p.parent().unwrap().to_path_buf();
        let abs = dir.join("det.add.xml");
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(&p, text.replace("ABS", &abs.display().to_string())).unwrap();
        let c = read_config(&p).unwrap();
        assert_eq!(c.net, Some(dir.join("nets/track.net.xml")));
        assert_eq!(c.routes, [dir.join("a.rou.xml"), dir.join("b.rou.xml")]);
        assert_eq!(c.additional, [abs]);
        assert_eq!(
            c.ignored,
            ["begin = 0", "step-length = 0.5", "fcd-output = fcd.xml"]
        );
    }

    #[test]
    fn files_that_are_no_configuration_are_refused_by_name() {
        let d = tempfile::tempdir().unwrap();
        let p = write(
            &d,
            "gone.sumocfg",
            "<configuration><route-files value=\"gone.rou.xml\"/></configuration>",
        );
        assert_eq!(
            read_config(&p).unwrap_err().to_string(),
            format!(
                "sumo.config = {}: route-files names {}, which is not there (relative paths are resolved against the configuration's folder, as SUMO does)",
                p.display(),
                p.parent().unwrap().join("gone.rou.xml").display()
            )
        );
        let missing = std::env::temp_dir().join("syncroad-no-such.sumocfg");
        assert_eq!(
            read_config(&missing).unwrap_err().to_string(),
            format!("sumo.config = {}: file not found", missing.display())
        );
        let p = write(&d, "bad.sumocfg", "<configuration><input>");
        assert!(read_config(&p)
            .unwrap_err()
            .to_string()
            .contains(": not XML ("));
        let p = write(&d, "net.sumocfg", "<net version=\"1.20\"/>");
        let e = read_config(&p).unwrap_err().to_string();
        assert!(
            e.contains("the root element is <net>; a SUMO configuration is <configuration>"),
            "{e}"
        );
        let p = write(
            &d,
            "novalue.sumocfg",
            "<configuration><input><net-file v=\"x\"/></input></configuration>",
        );
        assert_eq!(
            read_config(&p).unwrap_err().to_string(),
            format!(
                "sumo.config = {}: option <net-file> has no value (SUMO reads options as <net-file value=\"…\"/>, a file list separated by commas)",
                p.display()
            )
        );
        let p = write(
            &d,
            "emptyvalue.sumocfg",
            "<configuration><input><route-files value=\" , \"/></input></configuration>",
        );
        assert!(read_config(&p)
            .unwrap_err()
            .to_string()
            .contains("option <route-files> has no value"));
    }
}
