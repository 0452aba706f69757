//! Null-vector accuracy in `f32` on ill-conditioned systems: streaming QR + one-sided Jacobi
//! against the normal equations and nalgebra's SVD, all measured against an `f64` reference
//! computed from the *same* `f32`-rounded matrix (so only the algorithms' errors are compared).
//!
//! Run with `cargo test -p camgeom --test it linalg_conditioning:: -- --nocapture` for the table.

use camgeom::homography::Normalization;
use camgeom::linalg::{StreamingQr, svd_jacobi};
use camgeom::nalgebra::{Matrix3, Point2, SMatrix, SVector, SymmetricEigen};
use camgeom::rng::Pcg32;

const M: usize = 24;
type Tall<T> = SMatrix<T, M, 9>;

/// `|v - (v·r) r|` for unit `v`, `r`: the sine of the angle between the lines they span.
fn angle(v: &SVector<f64, 9>, r: &SVector<f64, 9>) -> f64 {
    let v = v.normalize();
    let r = r.normalize();
    (v - r * v.dot(&r)).norm()
}

/// Right singular vector of the smallest singular value, from nalgebra's SVD.
fn nalgebra_null<T: camgeom::Real>(a: &Tall<T>) -> SVector<f64, 9> {
    let svd = a.svd(false, true);
    let vt = svd.v_t.unwrap();
    let (i, _) = svd
        .singular_values
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.partial_cmp(y.1).unwrap())
        .unwrap();
    vt.row(i).transpose().map(|x| x.to_f64())
}

/// (a) streaming QR + Jacobi in f32.
fn ours(a: &Tall<f32>) -> SVector<f64, 9> {
    let mut qr = StreamingQr::<f32, 9>::new();
    for row in a.row_iter() {
        let mut r = [0.0f32; 9];
        r.iter_mut().zip(row.iter()).for_each(|(x, v)| *x = *v);
        qr.push_row(&r).unwrap();
    }
    qr.null_vector().unwrap().0.cast()
}

/// (b) normal equations `AᵀA` + symmetric eigen-decomposition, in f32.
fn normal_equations(a: &Tall<f32>) -> SVector<f64, 9> {
    let ata = a.transpose() * a;
    let e = SymmetricEigen::new(ata);
    let (i, _) = e
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.partial_cmp(y.1).unwrap())
        .unwrap();
    e.eigenvectors.column(i).into_owned().cast()
}

/// (a') Jacobi directly on the tall matrix (no QR), for reference.
fn jacobi_direct(a: &Tall<f32>) -> SVector<f64, 9> {
    svd_jacobi(a).unwrap().null_vector().cast()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

struct Row {
    label: String,
    errs: [Vec<f64>; 4],
}

fn report(rows: &mut [Row]) {
    println!(
        "{:<34} {:>22} {:>22} {:>22} {:>22}",
        "case (median / max sin angle)",
        "(a) QR+Jacobi f32",
        "(b) AtA+eig f32",
        "(c) nalgebra SVD f32",
        "(a') Jacobi on A f32"
    );
    for r in rows.iter_mut() {
        let cells: Vec<String> = r
            .errs
            .iter_mut()
            .map(|e| {
                let max = e.iter().cloned().fold(0.0, f64::max);
                format!("{:.2e} / {:.2e}", median(e), max)
            })
            .collect();
        println!(
            "{:<34} {:>22} {:>22} {:>22} {:>22}",
            r.label, cells[0], cells[1], cells[2], cells[3]
        );
    }
}

fn run(label: String, rows: &mut Vec<Row>, mats: impl Iterator<Item = Tall<f32>>) {
    let mut errs: [Vec<f64>; 4] = Default::default();
    for a in mats {
        let reference = nalgebra_null(&a.cast::<f64>());
        errs[0].push(angle(&ours(&a), &reference));
        errs[1].push(angle(&normal_equations(&a), &reference));
        errs[2].push(angle(&nalgebra_null(&a), &reference));
        errs[3].push(angle(&jacobi_direct(&a), &reference));
    }
    rows.push(Row { label, errs });
}

macro_rules! random_orthogonal {
    ($g:expr, $n:expr) => {
        SMatrix::<f64, $n, $n>::from_fn(|_, _| $g.normal()).qr().q()
    };
}

/// `A = U diag(σ) Vᵀ` with `σ₁ = 1 … σ₈ = 1/cond` (log-spaced) and `σ₉ = 0`, rounded to f32.
fn synthetic(g: &mut Pcg32, cond: f64) -> Tall<f32> {
    let u = random_orthogonal!(g, M);
    let v = random_orthogonal!(g, 9);
    let mut s = SMatrix::<f64, M, 9>::zeros();
    for i in 0..8 {
        s[(i, i)] = cond.powf(-(i as f64) / 7.0);
    }
    (u * s * v.transpose()).cast()
}

/// DLT rows of 12 noisy correspondences, optionally Hartley-normalised, in f32.
fn dlt_rows(g: &mut Pcg32, normalise: bool) -> Tall<f32> {
    let h = Matrix3::new(0.9, -0.12, 35.0, 0.08, 1.05, -20.0, 1.5e-4, -2e-4, 1.0);
    let src: Vec<Point2<f64>> = (0..M / 2)
        .map(|_| Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)))
        .collect();
    let dst: Vec<Point2<f64>> = src
        .iter()
        .map(|p| {
            let q = Point2::from_homogeneous(h * p.to_homogeneous()).unwrap();
            Point2::new(q.x + 0.5 * g.normal(), q.y + 0.5 * g.normal())
        })
        .collect();
    let (ns, nd) = if normalise {
        (
            Normalization::from_points(&src).unwrap(),
            Normalization::from_points(&dst).unwrap(),
        )
    } else {
        let id = Normalization {
            cx: 0.0,
            cy: 0.0,
            scale: 1.0,
        };
        (id, id)
    };
    let mut a = Tall::<f64>::zeros();
    for (i, (s, d)) in src.iter().zip(dst.iter()).enumerate() {
        let x = ns.apply(s);
        let u = nd.apply(d);
        let r1 = [0.0, 0.0, 0.0, -x.x, -x.y, -1.0, u.y * x.x, u.y * x.y, u.y];
        let r2 = [x.x, x.y, 1.0, 0.0, 0.0, 0.0, -u.x * x.x, -u.x * x.y, -u.x];
        for j in 0..9 {
            a[(2 * i, j)] = r1[j];
            a[(2 * i + 1, j)] = r2[j];
        }
    }
    a.cast()
}

#[test]
fn null_vector_accuracy_f32() {
    let mut g = Pcg32::new(2024);
    let mut rows = Vec::new();
    for &cond in &[1e2, 1e3, 1e4, 1e5, 1e6] {
        let mats: Vec<Tall<f32>> = (0..25).map(|_| synthetic(&mut g, cond)).collect();
        run(
            format!("synthetic, cond {cond:.0e}"),
            &mut rows,
            mats.into_iter(),
        );
    }
    let mats: Vec<Tall<f32>> = (0..25).map(|_| dlt_rows(&mut g, true)).collect();
    run("DLT 12 pts, normalised".into(), &mut rows, mats.into_iter());
    let mats: Vec<Tall<f32>> = (0..25).map(|_| dlt_rows(&mut g, false)).collect();
    run("DLT 12 pts, raw pixels".into(), &mut rows, mats.into_iter());
    report(&mut rows);

    for r in &mut rows {
        let ours_med = median(&mut r.errs[0]);
        let ne_med = median(&mut r.errs[1]);
        let ours_max = r.errs[0].iter().cloned().fold(0.0, f64::max);
        let ne_max = r.errs[1].iter().cloned().fold(0.0, f64::max);
        // At least as good as the normal equations (which square the condition number).
        assert!(ours_med <= ne_med, "{}: {ours_med} > {ne_med}", r.label);
        assert!(ours_max <= ne_max, "{}: {ours_max} > {ne_max}", r.label);
        // And within a small factor of nalgebra's f32 SVD.
        let na_med = median(&mut r.errs[2]);
        assert!(ours_med <= 4.0 * na_med.max(1e-7), "{}", r.label);
    }
}
