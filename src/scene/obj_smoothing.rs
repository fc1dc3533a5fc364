//! OBJ smoothing groups for files without normals: faces under `s 1` (any group but `off` or
//! `0`) are shaded smooth, the others flat, as Blender 5.2's importer shades them (checked).
//!
//! A file with `vn` lines carries its own shading and is left as it is. Without them, each
//! smooth face's corner takes the normal of its vertex: the sum of the unit normals of the
//! smooth faces of the same object (`o`) that share the vertex, each weighted by the face's
//! angle at it (Blender's corner normals; like Blender, the group's number does not separate
//! faces: two groups that meet are smooth across the seam). Flat faces keep their own normal.
//!
//! tobj reads no `s` statements, so the normals are written into the text as `vn` lines with
//! every face corner naming its normal, and tobj parses that text.

use glam::Vec3;

/// The OBJ `text` with normals written in for its smoothing groups (see the module docs), or
/// `None` when there is nothing to do (the file has normals, or no face is in a smoothing
/// group) or the text is not what this reads with certainty (a line continued with `\`, an
/// unreadable `v` line or face index, a corner that names a normal): then the file is parsed
/// as it is, and its errors are tobj's and the loader's.
pub(crate) fn with_smooth_normals(text: &str) -> Option<String> {
    if !has_smooth_group(text) {
        return None;
    }
    use std::fmt::Write;
    let faces = read_faces(text)?;
    let (normals, corner_normals) = normals_of(&faces);
    let mut out = String::with_capacity(text.len() + 40 * normals.len() + 8 * faces.corners.len());
    // Writing into `out` cannot fail.
    for n in &normals {
        let _ = writeln!(out, "vn {} {} {}", n.x, n.y, n.z);
    }
    let mut next_corner = 0;
    for line in text.split_inclusive('\n') {
        if keyword(line) != Some("f") {
            out.push_str(line);
            continue;
        }
        out.push('f');
        for token in line.split_ascii_whitespace().skip(1) {
            let mut parts = token.split('/');
            let v = parts.next().unwrap_or_default();
            let vt = parts.next().unwrap_or_default();
            let _ = write!(out, " {v}/{vt}/{}", corner_normals[next_corner] + 1);
            next_corner += 1;
        }
        out.push('\n');
    }
    Some(out)
}

/// Whether any line of `text` is an `s` statement of a smoothing group (not `off` or `0`):
/// found from the letter's occurrences with `memchr`, which lines of numbers have none (a
/// scan of every line was 7% of the Stanford bunny's load).
fn has_smooth_group(text: &str) -> bool {
    let bytes = text.as_bytes();
    memchr::memchr_iter(b's', bytes).any(|at| {
        let indent = bytes[..at]
            .iter()
            .rev()
            .take_while(|b| matches!(b, b' ' | b'\t'))
            .count();
        let starts_line = at == indent || bytes[at - indent - 1] == b'\n';
        starts_line
            && bytes.get(at + 1).is_some_and(|b| matches!(b, b' ' | b'\t'))
            && smooth_statement(first_line(&text[at..])) == Some(true)
    })
}

/// `text` up to its first line break.
fn first_line(text: &str) -> &str {
    text.lines().next().unwrap_or_default()
}

/// The faces as the text gives them, in order: each one's object, whether it is smooth, and
/// where its corners start in `corners` (each corner's position index and position).
struct Faces {
    faces: Vec<(usize, bool, usize)>,
    corners: Vec<(usize, Vec3)>,
}

impl Faces {
    /// Face `f`'s object, smoothness and corners.
    fn face(&self, f: usize) -> (usize, bool, &[(usize, Vec3)]) {
        let (object, smooth, start) = self.faces[f];
        let end = self
            .faces
            .get(f + 1)
            .map_or(self.corners.len(), |next| next.2);
        (object, smooth, &self.corners[start..end])
    }
}

/// The first word of `line`.
fn keyword(line: &str) -> Option<&str> {
    line.split_ascii_whitespace().next()
}

/// For an `s` line, whether the faces after it are smooth (`s off` and `s 0` are flat).
fn smooth_statement(line: &str) -> Option<bool> {
    let mut words = line.split_ascii_whitespace();
    (words.next() == Some("s")).then(|| !matches!(words.next(), Some("off" | "0") | None))
}

/// The faces of `text` in order, or `None` for anything not read with certainty.
fn read_faces(text: &str) -> Option<Faces> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces = Faces {
        faces: Vec::new(),
        corners: Vec::new(),
    };
    let (mut object, mut smooth) = (0, false);
    for line in text.lines() {
        if line.trim_end().ends_with('\\') {
            return None;
        }
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let mut xyz = [0.0f32; 3];
                for c in &mut xyz {
                    *c = words.next()?.parse().ok()?;
                }
                positions.push(Vec3::from(xyz));
            }
            Some("vn") => return None,
            Some("o") => object += 1,
            Some("s") => smooth = smooth_statement(line)?,
            Some("f") => {
                let start = faces.corners.len();
                for token in words {
                    let mut parts = token.split('/');
                    let index: i64 = parts.next()?.parse().ok()?;
                    // A corner naming a normal in a file without normals: not ours to read.
                    if parts.nth(1).is_some_and(|n| !n.is_empty()) {
                        return None;
                    }
                    let count = positions.len() as i64;
                    let at = if index < 0 { count + index } else { index - 1 };
                    let at = usize::try_from(at).ok().filter(|&i| i < positions.len())?;
                    faces.corners.push((at, positions[at]));
                }
                if faces.corners.len() - start < 3 {
                    return None;
                }
                faces.faces.push((object, smooth, start));
            }
            _ => {}
        }
    }
    Some(faces)
}

/// The normals to write, and each face corner's index into them (in the order of
/// `faces.corners`): a smooth face's corner the normal of its vertex in its object, a flat
/// face's corners its own normal.
fn normals_of(faces: &Faces) -> (Vec<Vec3>, Vec<usize>) {
    let unit_normal = |corners: &[(usize, Vec3)]| {
        // Newell's normal: the polygon's area vector, exact for planar faces and a fair
        // average for the rest.
        let n = corners.len();
        let sum = (0..n).fold(Vec3::ZERO, |acc, i| {
            let (a, b) = (corners[i].1, corners[(i + 1) % n].1);
            acc + Vec3::new(
                (a.y - b.y) * (a.z + b.z),
                (a.z - b.z) * (a.x + b.x),
                (a.x - b.x) * (a.y + b.y),
            )
        });
        sum.normalize_or_zero()
    };
    let mut normals: Vec<Vec3> = Vec::new();
    // The normal of each position in the current object (objects only follow one another:
    // the table starts again at each). `usize::MAX`: none yet.
    let mut vertex_normal: Vec<usize> = Vec::new();
    let mut current_object = None;
    let mut corner_normals = Vec::with_capacity(faces.corners.len());
    for f in 0..faces.faces.len() {
        let (object, smooth, corners) = faces.face(f);
        let normal = unit_normal(corners);
        if !smooth {
            normals.push(normal);
            corner_normals.extend(std::iter::repeat_n(normals.len() - 1, corners.len()));
            continue;
        }
        if current_object != Some(object) {
            current_object = Some(object);
            vertex_normal.fill(usize::MAX);
        }
        let n = corners.len();
        for i in 0..n {
            let (at, p) = corners[i];
            let to_next = (corners[(i + 1) % n].1 - p).normalize_or_zero();
            let to_previous = (corners[(i + n - 1) % n].1 - p).normalize_or_zero();
            let angle = to_next.dot(to_previous).clamp(-1.0, 1.0).acos();
            if vertex_normal.len() <= at {
                vertex_normal.resize(at + 1, usize::MAX);
            }
            if vertex_normal[at] == usize::MAX {
                vertex_normal[at] = normals.len();
                normals.push(Vec3::ZERO);
            }
            normals[vertex_normal[at]] += normal * angle;
            corner_normals.push(vertex_normal[at]);
        }
    }
    // Smooth sums to unit length (flat normals already are: unchanged).
    for n in &mut normals {
        *n = n.normalize_or_zero();
    }
    (normals, corner_normals)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normals written for a face's corners, read back from the rewritten text.
    fn corner_normals(text: &str) -> Vec<Vec<Vec3>> {
        let out = with_smooth_normals(text).expect("rewritten");
        let normals: Vec<Vec3> = out
            .lines()
            .filter(|l| l.starts_with("vn "))
            .map(|l| {
                let c: Vec<f32> = l[3..].split(' ').map(|x| x.parse().unwrap()).collect();
                Vec3::new(c[0], c[1], c[2])
            })
            .collect();
        out.lines()
            .filter(|l| l.starts_with("f "))
            .map(|l| {
                l[2..]
                    .split(' ')
                    .map(|t| normals[t.rsplit('/').next().unwrap().parse::<usize>().unwrap() - 1])
                    .collect()
            })
            .collect()
    }

    /// Blender 5.2's corner normals of the same file (bpy 5.2.3, `mesh.corner_normals`, three
    /// decimals): faces in groups 1 and 2 that share vertices, all smooth across the seam.
    #[test]
    fn smooth_faces_get_blenders_corner_normals() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0.3\nv 0 1 0\nv 2 0 0.5\n\
                    s 1\nf 1 2 3\nf 1 3 4\ns 2\nf 2 5 3\n";
        let blender = [
            [
                [-0.147, -0.147, 0.978],
                [-0.212, -0.281, 0.936],
                [-0.256, -0.191, 0.948],
            ],
            [
                [-0.147, -0.147, 0.978],
                [-0.256, -0.191, 0.948],
                [-0.287, 0.0, 0.958],
            ],
            [
                [-0.212, -0.281, 0.936],
                [-0.432, -0.259, 0.864],
                [-0.256, -0.191, 0.948],
            ],
        ];
        for (ours, theirs) in corner_normals(text).iter().zip(blender) {
            for (n, b) in ours.iter().zip(theirs) {
                assert!(
                    (*n - Vec3::from(b)).abs().max_element() < 1.5e-3,
                    "{n} vs {b:?}"
                );
            }
        }
    }

    /// `s off` (or `s 0`) faces keep their own normal; faces of different objects do not
    /// smooth into each other; relative indices and texture coordinates are kept.
    #[test]
    fn flat_faces_and_objects_stay_apart() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\n\
                    s 1\nf 1/1 2/1 3/1\ns off\nf 1 3 4\no other\ns 1\nf -4 -2 -1\n";
        let normals = corner_normals(text);
        assert_eq!(normals[0], vec![Vec3::Z; 3]);
        assert_eq!(normals[1], vec![Vec3::X; 3]);
        assert_eq!(normals[2], vec![Vec3::X; 3]);
        let out = with_smooth_normals(text).unwrap();
        assert!(out.contains("\nf 1/1/1 2/1/2 3/1/3\n"), "{out}");
        assert!(out.contains("\nf -4//"), "{out}");
    }

    /// Nothing to do, or nothing read with certainty: the text is parsed as it is.
    #[test]
    fn files_with_normals_or_without_groups_are_left_alone() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        assert!(with_smooth_normals(&format!("{tri}f 1 2 3\n")).is_none());
        assert!(with_smooth_normals(&format!("{tri}s off\nf 1 2 3\n")).is_none());
        assert!(with_smooth_normals(&format!("{tri}vn 0 0 1\ns 1\nf 1//1 2//1 3//1\n")).is_none());
        assert!(with_smooth_normals(&format!("{tri}s 1\nf 1 2 9\n")).is_none());
        assert!(with_smooth_normals(&format!("{tri}s 1\nf 1 2 \\\n3\n")).is_none());
        assert!(with_smooth_normals(&format!("{tri}s 1\nf 1 2 3\n")).is_some());
        // An indented statement counts; an 's' inside other lines does not.
        assert!(with_smooth_normals(&format!("{tri}\t s 1\nf 1 2 3\n")).is_some());
        assert!(with_smooth_normals(&format!("usemtl glass s 1\n# s 1\n{tri}f 1 2 3\n")).is_none());
    }
}
