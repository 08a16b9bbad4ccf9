//! Files the commands write for the user (reports, twin files, replay CSVs).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// Write `bytes` to `path` whole or not at all: into `<path>.partial` beside it, then
/// renamed, so a reader never sees half a file and a failed write leaves no `path`.
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = partial_path(path);
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

/// `<path>.partial`: where [`write_whole`] writes before renaming.
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_partial_file_sits_beside_the_target_with_its_whole_name() {
        assert_eq!(
            partial_path(Path::new("/tmp/x/TWIN.yaml")),
            Path::new("/tmp/x/TWIN.yaml.partial")
        );
        assert_eq!(partial_path(Path::new("r")), Path::new("r.partial"));
    }
}
