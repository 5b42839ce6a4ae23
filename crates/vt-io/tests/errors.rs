//! Errors keep their types across crates: a vt-io failure inside vt-core's frame loop comes back
//! as `vt_core::Error::External` holding the `vt_io::Error`, and its chain names the file once.

use std::error::Error as _;

use vt_core::analysis::FrameSource;
use vt_io::frames::FolderSource;

#[test]
fn a_broken_frame_keeps_its_vt_io_type_inside_vt_core_errors() {
    let dir = tempfile::tempdir().unwrap();
    let good = image::RgbImage::from_pixel(8, 6, image::Rgb([10, 20, 30]));
    good.save(dir.path().join("f000.png")).unwrap();
    good.save(dir.path().join("f001.png")).unwrap();
    // A PNG signature followed by garbage: listed as a frame, fails to decode.
    std::fs::write(dir.path().join("f002.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();

    let mut src = FolderSource::open(dir.path()).unwrap();
    let err = src.for_each_frame(&mut |_, _| Ok(())).unwrap_err();
    let vt_core::Error::External { view, source } = &err else {
        panic!("expected Error::External, got {err:?}");
    };
    assert_eq!(view, &dir.path().display().to_string());
    let inner = source
        .inner()
        .downcast_ref::<vt_io::Error>()
        .expect("the source is the vt_io::Error itself");
    assert!(matches!(inner, vt_io::Error::Image { path, .. } if path.ends_with("f002.png")));

    // The chain, printed cause by cause, names the broken file exactly once.
    let mut chain = vec![err.to_string()];
    let mut cause = err.source();
    while let Some(c) = cause {
        chain.push(c.to_string());
        cause = c.source();
    }
    let text = chain.join(": ");
    assert_eq!(text.matches("f002.png").count(), 1, "{text}");
}
