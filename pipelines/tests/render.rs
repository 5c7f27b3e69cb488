//! Frames through the OpenGL-like pipeline on the clocked machine.

use imagine_pipelines::opengl::render::render;
use imagine_pipelines::scene::parse_tri;
use imagine_units::desc::MachineDesc;

#[test]
fn two_overlapping_triangles() {
    let scene = parse_tri(
        "two",
        "32 32\n\
         2 2 0.5 1 0 0  30 2 0.5 1 0 0  2 30 0.5 1 0 0\n\
         4 4 0.25 0 1 0  28 4 0.25 0 1 0  16 28 0.75 0 1 0\n",
    )
    .unwrap();
    let desc = MachineDesc::gold8();
    let f = render(&scene, &desc, None, |_, _| {}).unwrap();
    println!("{:#?}", f.stats);
    for y in (0..32).rev() {
        let row: String = (0..32)
            .map(|x| match f.pixels[y * 32 + x] & 0xFFFFFF {
                0 => '.',
                0xFF => 'R',
                0xFF00 => 'G',
                _ => '?',
            })
            .collect();
        println!("{row}");
    }
    println!("{:x?}", &f.pixels[..32]);
    assert_eq!(f.pixels[3 * 32 + 3] & 0xFFFFFF, 0xFF, "red corner");
    assert_eq!(
        f.pixels[8 * 32 + 16] & 0xFFFFFF,
        0xFF00,
        "green in front at the bottom"
    );
}
