use std::time::Instant;
fn main() {
    let p = std::env::args().nth(1).unwrap();
    let n: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(50);
    let base = meshtracer::Scene::load(&p).unwrap();
    let mut ts = vec![];
    let mut ls = vec![];
    for _ in 0..n {
        let t0 = Instant::now();
        let s = meshtracer::Scene::load(&p).unwrap();
        ls.push(t0.elapsed().as_secs_f64() * 1e3);
        let mut s2 = s;
        let t = Instant::now();
        meshtracer::scene::tangents::generate_missing(&mut s2);
        ts.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    ls.sort_by(|a, b| a.partial_cmp(b).unwrap());
    println!(
        "tris {} load median {:.2} min {:.2} ms; tangents median {:.2} min {:.2} ms",
        base.soup.len(),
        ls[n / 2],
        ls[0],
        ts[n / 2],
        ts[0]
    );
}
