//! Invalid input: NaN and infinite numbers in each kind of file (`.tri`, scene TOML, OBJ
//! positions, normals and texture coordinates, `.bpt` control points) and zero-size
//! windows. Each case passes when loading (or, at the latest, rendering) fails with an
//! error that names the file and the key or line.

use super::case::{Case, Invalid, Kind};

fn invalid(
    name: &'static str,
    about: &'static str,
    files: Vec<(&'static str, String)>,
    must_name: Vec<&'static str>,
) -> Case {
    Case {
        name,
        family: "invalid",
        about,
        kind: Kind::Invalid(Invalid { files, must_name }),
        known_failure: None,
    }
}

const WINDOW: &str = "[window]\nwidth = 32\nheight = 32\n[camera]\neye = [0.0, 0.0, 4.0]\n\
    target = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov_y = 40.0\nnear = 1.0\nfar = 10.0\n";

/// A scene file drawing `bad.obj` (lit when it has normals, textured when it has texture
/// coordinates) and the OBJ.
fn obj_scene(obj: &str, lit: bool, textured: bool) -> Vec<(&'static str, String)> {
    let material = match (lit, textured) {
        (true, _) => {
            "[[light]]\nposition = [1.0, 1.0, 5.0]\n[[material]]\nname = \"m\"\nshader = \"lit\"\n"
        }
        (false, true) => {
            "[[texture]]\nname = \"t\"\nprocedural = { kind = \"checker\", size = 8, cells = 2, \
             colours = [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]] }\n\
             [[material]]\nname = \"m\"\nshader = \"unlit\"\ntextures = [\"t\"]\n"
        }
        (false, false) => "[[material]]\nname = \"m\"\nshader = \"unlit\"\n",
    };
    vec![
        (
            "scene.toml",
            format!("{WINDOW}{material}[[object]]\nmesh = \"bad.obj\"\nmaterial = \"m\"\n"),
        ),
        ("bad.obj", obj.to_string()),
    ]
}

pub fn cases() -> Vec<Case> {
    vec![
        invalid(
            "nan-in-tri",
            "a NaN x in a .tri file: an error naming the file, line and coordinate",
            vec![(
                "bad.tri",
                "16 16\n1 1 0.5 1 1 1  14 2 0.5 1 1 1  8 14 0.5 1 1 1\n\
                 nan 1 0.5 1 1 1  14 2 0.5 1 1 1  8 14 0.5 1 1 1\n"
                    .into(),
            )],
            vec!["bad.tri", "line 3", "vertex 0 x"],
        ),
        invalid(
            "inf-in-tri",
            "an infinite depth in a .tri file: an error naming the file, line and coordinate",
            vec![(
                "bad.tri",
                "16 16\n1 1 0.5 1 1 1  14 2 inf 1 1 1  8 14 0.5 1 1 1\n".into(),
            )],
            vec!["bad.tri", "line 2", "vertex 1 z"],
        ),
        invalid(
            "zero-window-tri",
            "a .tri file with a 0 x 16 window: an error naming the file and the window",
            vec![(
                "bad.tri",
                "0 16\n1 1 0.5 1 1 1  14 2 0.5 1 1 1  8 14 0.5 1 1 1\n".into(),
            )],
            vec!["bad.tri", "line 1", "window"],
        ),
        invalid(
            "zero-window-toml",
            "a scene file with width = 0: an error naming the file and `window.width`",
            vec![(
                "scene.toml",
                WINDOW.replace("width = 32", "width = 0")
                    + "[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 1 }\n",
            )],
            vec!["scene.toml", "window.width"],
        ),
        invalid(
            "nan-in-toml",
            "a NaN translation in a scene file: an error naming the file and `object[0].translate`",
            vec![(
                "scene.toml",
                format!(
                    "{WINDOW}[[object]]\nprimitive = {{ kind = \"icosphere\", subdivisions = 1 }}\n\
                     translate = [0.0, nan, 0.0]\n"
                ),
            )],
            vec!["scene.toml", "object[0].translate"],
        ),
        invalid(
            "inf-camera-toml",
            "an infinite eye position: an error naming the file and `camera.eye`",
            vec![(
                "scene.toml",
                WINDOW.replace("eye = [0.0, 0.0, 4.0]", "eye = [0.0, -inf, 4.0]")
                    + "[[object]]\nprimitive = { kind = \"icosphere\", subdivisions = 1 }\n",
            )],
            vec!["scene.toml", "camera.eye"],
        ),
        invalid(
            "nan-vertex-obj",
            "a NaN vertex in an OBJ: an error naming the scene file and `object[0].mesh`",
            obj_scene("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", false, false),
            vec!["scene.toml", "object[0].mesh"],
        ),
        invalid(
            "inf-normal-obj",
            "an infinite normal in a lit OBJ: an error naming the scene file and `object[0].mesh`",
            obj_scene(
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 inf 1\nf 1//1 2//2 3//1\n",
                true,
                false,
            ),
            vec!["scene.toml", "object[0].mesh"],
        ),
        invalid(
            "nan-texcoord-obj",
            "a NaN texture coordinate in a textured OBJ: an error naming the scene file and `object[0].mesh`",
            obj_scene(
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt nan 0\nf 1/1 2/2 3/1\n",
                false,
                true,
            ),
            vec!["scene.toml", "object[0].mesh"],
        ),
        invalid(
            "nan-in-bpt",
            "a NaN control point in a .bpt file: an error naming the scene file, `object[0].patches` and the point",
            vec![
                (
                    "scene.toml",
                    format!("{WINDOW}[[object]]\npatches = \"bad.bpt\"\ntessellate = 2\n"),
                ),
                ("bad.bpt", {
                    let mut t = String::from("1\n3 3\n");
                    for k in 0..16 {
                        if k == 5 {
                            t += "0.3 nan 0\n";
                        } else {
                            t += &format!("{} {} 0\n", k % 4, k / 4);
                        }
                    }
                    t
                }),
            ],
            vec!["scene.toml", "object[0].patches", "point 5"],
        ),
    ]
}
