//! Readers never panic on damaged files: every format is read back from truncated copies and
//! from copies with bytes overwritten, and must answer with `Ok` or an error.

use super::gmsh::{read_msh, write_msh};
use super::obj::{read_obj, write_obj};
use super::ply::{VertexAttributes, read_ply, write_ply};
use super::stl::{StlEncoding, read_stl, write_stl};
use super::test_meshes::{cube_surface, kuhn_cube};
use super::vtu::{VtuEncoding, read_vtu, write_vtu};
use super::{MeshIoError, VolumeMesh};

type Reader = fn(&std::path::Path) -> Result<(), MeshIoError>;

#[test]
fn damaged_files_give_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let surface = cube_surface();
    let volume = VolumeMesh::from_tets(kuhn_cube());
    let attrs = VertexAttributes {
        quality: Some(vec![0.5; 8]),
        colors: None,
    };
    let files: Vec<(&str, Reader)> = vec![
        ("a.ply", |p| read_ply(p).map(drop)),
        ("b.stl", |p| read_stl(p).map(drop)),
        ("c.stl", |p| read_stl(p).map(drop)),
        ("d.obj", |p| read_obj(p).map(drop)),
        ("e.vtu", |p| read_vtu(p).map(drop)),
        ("f.vtu", |p| read_vtu(p).map(drop)),
        ("g.msh", |p| read_msh(p).map(drop)),
    ];
    write_ply(&dir.path().join("a.ply"), &surface, &attrs).unwrap();
    write_stl(&dir.path().join("b.stl"), &surface, StlEncoding::Binary).unwrap();
    write_stl(&dir.path().join("c.stl"), &surface, StlEncoding::Ascii).unwrap();
    write_obj(&dir.path().join("d.obj"), &surface).unwrap();
    write_vtu(&dir.path().join("e.vtu"), &volume, &[], VtuEncoding::Ascii).unwrap();
    write_vtu(&dir.path().join("f.vtu"), &volume, &[], VtuEncoding::Base64).unwrap();
    write_msh(&dir.path().join("g.msh"), &volume, &Default::default()).unwrap();
    let damaged = dir.path().join("damaged");
    let mut errors = 0;
    for (name, read) in files {
        let good = std::fs::read(dir.path().join(name)).unwrap();
        read(&dir.path().join(name)).unwrap();
        let step = (good.len() / 97).max(1);
        let mut variants: Vec<Vec<u8>> = (0..good.len())
            .step_by(step)
            .map(|n| good[..n].to_vec())
            .collect();
        for (k, at) in (0..good.len()).step_by(step).enumerate() {
            let mut bad = good.clone();
            bad[at] = [b'9', b'-', 0xff, b' ', b'\n', b'<', 0][k % 7];
            variants.push(bad);
        }
        for bytes in variants {
            std::fs::write(&damaged, &bytes).unwrap();
            errors += usize::from(read(&damaged).is_err());
        }
    }
    // Most damaged copies are refused (a few overwritten digits still parse).
    assert!(errors > 700, "{errors}");
}
