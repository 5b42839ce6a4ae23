use super::*;

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    v
}

#[test]
fn replaces_only_its_own_kind_and_never_foreign_folders() {
    let root = tempfile::tempdir().unwrap();
    let target = root.path().join("scene");
    // A first output, then a replacement.
    let o = Output::dir(&target, OutputKind::Scene, &[]).unwrap();
    std::fs::write(o.path().join("a.txt"), "1").unwrap();
    o.commit().unwrap();
    let o = Output::dir(&target, OutputKind::Scene, &[]).unwrap();
    std::fs::write(o.path().join("b.txt"), "2").unwrap();
    {
        // An unfinished one is dropped: the committed one stays.
        let d = Output::dir(&root.path().join("other"), OutputKind::Scene, &[]).unwrap();
        std::fs::write(d.path().join("x"), "x").unwrap();
    }
    o.commit().unwrap();
    assert_eq!(entries(&target), vec![".vt-output", "b.txt"]);
    assert_eq!(entries(root.path()), vec!["scene"], "no temporary left");
    // Another kind, a user file inside, a foreign folder, a file: refused, untouched.
    let e = Output::dir(&target, OutputKind::Frames, &[])
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("is a vt scene output, not a vt frames output"),
        "{e}"
    );
    std::fs::write(target.join("photo.jpg"), "mine").unwrap();
    let e = Output::dir(&target, OutputKind::Scene, &[])
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("also holds photo.jpg"), "{e}");
    let foreign = root.path().join("photos");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("p.jpg"), "x").unwrap();
    let e = Output::dir(&foreign, OutputKind::Scene, &[])
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("not a vt output (a folder with 1 entry and"),
        "{e}"
    );
    let file = root.path().join("notes.txt");
    std::fs::write(&file, "x").unwrap();
    let e = Output::dir(&file, OutputKind::Scene, &[])
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("is a file"), "{e}");
    let e = Output::dir(&file.join("x"), OutputKind::Scene, &[])
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("notes.txt is a file, not a folder"), "{e}");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    assert_eq!(
        std::fs::read_to_string(target.join("photo.jpg")).unwrap(),
        "mine"
    );
}

#[test]
fn refuses_inputs_and_folders_holding_them() {
    let root = tempfile::tempdir().unwrap();
    let frames = root.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    let f = frames.join("f0.png");
    std::fs::write(&f, "x").unwrap();
    for (target, want) in [
        (&frames, "is one of this run's inputs"),
        (&root.path().to_path_buf(), "holds"),
    ] {
        let e = Output::dir(target, OutputKind::Scene, &[&frames])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains(want), "{e}");
    }
    // Through a relative path with `..` too.
    let sneaky = frames.join("..").join("frames");
    assert!(Output::dir(&sneaky, OutputKind::Scene, &[&f]).is_err());
    assert!(f.exists());
}

#[test]
fn stale_temporaries_of_dead_processes_are_removed() {
    let root = tempfile::tempdir().unwrap();
    // A pid that cannot be running (above Linux's pid_max limit of 2^22).
    let dead = root.path().join(".scene.vt-tmp-4194305");
    std::fs::create_dir(&dead).unwrap();
    std::fs::write(dead.join("half"), "x").unwrap();
    let alive = root.path().join(format!(".scene.vt-tmp-{}", 1));
    std::fs::create_dir(&alive).unwrap();
    let user = root.path().join(".tmp-notes");
    std::fs::write(&user, "x").unwrap();
    // Another program's temporary of a process that is gone: not vt's, so kept.
    let other = root.path().join(".scene.tmp-4194305");
    std::fs::write(&other, "x").unwrap();
    let o = Output::dir(&root.path().join("scene"), OutputKind::Scene, &[]).unwrap();
    o.commit().unwrap();
    let left = entries(root.path());
    if Path::new("/proc/self").exists() {
        assert!(
            !left.contains(&".scene.vt-tmp-4194305".to_string()),
            "{left:?}"
        );
    }
    assert!(
        left.contains(&".scene.vt-tmp-1".to_string()),
        "pid 1 is alive: {left:?}"
    );
    assert!(left.contains(&".tmp-notes".to_string()), "{left:?}");
    assert!(left.contains(&".scene.tmp-4194305".to_string()), "{left:?}");
    assert_eq!(stale_pid(".a.b.vt-tmp-12"), Some(12));
    assert_eq!(stale_pid(".a.vt-old-7"), Some(7));
    assert_eq!(stale_pid(".a.vt-del-7"), Some(7));
    assert_eq!(
        discard_name(Path::new("/x/.a.b.vt-tmp-12")),
        Some(PathBuf::from("/x/.a.b.vt-del-12"))
    );
    assert_eq!(discard_name(Path::new("/x/.a.tmp-12")), None);
    assert_eq!(stale_pid(".a.tmp-12"), None);
    assert_eq!(stale_pid(".vt-tmp-7"), None);
    assert_eq!(stale_pid("a.vt-tmp-7"), None);
    assert_eq!(stale_pid(".a.vt-tmp-7x"), None);
}

#[test]
fn file_markers_round_trip() {
    let root = tempfile::tempdir().unwrap();
    let img = image::RgbImage::from_pixel(5, 4, image::Rgb([1, 2, 3]));
    for (name, fmt) in [
        ("a.png", image::ImageFormat::Png),
        ("a.jpg", image::ImageFormat::Jpeg),
    ] {
        let target = root.path().join(name);
        let o = Output::file(&target, OutputKind::Image, &[]).unwrap();
        img.save_with_format(o.path(), fmt).unwrap();
        o.commit().unwrap();
        assert!(has_marker(&target, OutputKind::Image).unwrap(), "{name}");
        assert!(!has_marker(&target, OutputKind::Video).unwrap(), "{name}");
        let back = image::open(&target).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (5, 4), "{name} still decodes");
        // Replaceable now; a plain image of the user's is not.
        assert!(Output::file(&target, OutputKind::Image, &[]).is_ok());
        let user = root.path().join(format!("user_{name}"));
        img.save_with_format(&user, fmt).unwrap();
        let e = Output::file(&user, OutputKind::Image, &[])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("not a vt image output"), "{e}");
    }
    // A GIF (1x1, hand-made): the comment goes before the trailer.
    let gif = root.path().join("a.gif");
    let o = Output::file(&gif, OutputKind::Video, &[]).unwrap();
    let bytes: &[u8] = b"GIF89a\x01\x00\x01\x00\x80\x00\x00\xff\xff\xff\x00\x00\x00,\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;";
    std::fs::write(o.path(), bytes).unwrap();
    o.commit().unwrap();
    assert!(has_marker(&gif, OutputKind::Video).unwrap());
    let back = std::fs::read(&gif).unwrap();
    assert_eq!(&back[..bytes.len() - 1], &bytes[..bytes.len() - 1]);
    assert_eq!(back.last(), Some(&0x3B));
    assert_eq!(shorten("short"), "short");
    assert_eq!(num(1e-300), "1e-300");
    assert_eq!(num(2.5), "2.5");
    assert_eq!(
        shorten(&"9".repeat(309)),
        format!("{}... (309 characters)", "9".repeat(32))
    );
}

/// The mark records the very file (or folder) vt wrote there: a copy of a vt output, one
/// copied over another vt output, or one moved from another name is refused as a target and
/// kept; vt's own output at its place is still replaced.
#[test]
fn a_copied_mark_does_not_make_a_file_replaceable() {
    let root = tempfile::tempdir().unwrap();
    let img = image::RgbImage::from_pixel(5, 4, image::Rgb([1, 2, 3]));
    let target = root.path().join("a.png");
    let write = |t: &Path| {
        let o = Output::file(t, OutputKind::Image, &[]).unwrap();
        img.save_with_format(o.path(), image::ImageFormat::Png)
            .unwrap();
        o.commit().unwrap();
    };
    write(&target);
    write(&target);
    let refused = |t: &Path| {
        let e = Output::file(t, OutputKind::Image, &[])
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("not a vt image output written here"), "{e}");
    };
    // A copy under another name.
    let copy = root.path().join("holiday.png");
    std::fs::copy(&target, &copy).unwrap();
    refused(&copy);
    // Copied over another vt output (the same inode there, other bytes).
    let other = root.path().join("b.png");
    write(&other);
    std::fs::copy(&target, &other).unwrap();
    refused(&other);
    // Moved to another name.
    let moved = root.path().join("moved.png");
    std::fs::rename(&target, &moved).unwrap();
    refused(&moved);
    assert!(moved.exists() && copy.exists() && other.exists());
    // A folder output copied elsewhere.
    let dir = root.path().join("frames");
    let o = Output::dir(&dir, OutputKind::Frames, &[]).unwrap();
    std::fs::write(o.path().join("f.png"), b"x").unwrap();
    o.commit().unwrap();
    assert!(Output::dir(&dir, OutputKind::Frames, &[]).is_ok());
    let dcopy = root.path().join("frames-copy");
    std::fs::create_dir(&dcopy).unwrap();
    for name in ["f.png", MARKER_FILE] {
        std::fs::copy(dir.join(name), dcopy.join(name)).unwrap();
    }
    let e = Output::dir(&dcopy, OutputKind::Frames, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("not the folder vt wrote here"), "{e}");
}
