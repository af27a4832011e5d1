//! The `Field` trait: what every polygonizer evaluates.

use std::ops::Range;

use glam::DVec3;

use crate::Aabb;

/// A scalar field `f: R³ → R` whose zero set is the surface.
///
/// Convention (DESIGN.md): **inside is `f < 0`**, outside `f > 0`, and the outward normal is
/// `∇f / |∇f|`. A field may return NaN or ±∞ at some points; polygonizers report that rather
/// than panic.
///
/// Only [`Field::eval`] is required. Polygonizers call the batch methods, so a field that can
/// evaluate many points faster than one at a time (the compiled formulas do) should override
/// them. Implementations must be deterministic: the same point gives the same value on every
/// thread and every call, which is what makes meshes independent of the thread count.
pub trait Field: Send + Sync {
    /// The value at one point.
    fn eval(&self, p: DVec3) -> f64;

    /// Values at many points: `out[i] = f(points[i])`. `out.len()` must equal `points.len()`.
    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        debug_assert_eq!(points.len(), out.len());
        for (p, o) in points.iter().zip(out.iter_mut()) {
            *o = self.eval(*p);
        }
    }

    /// Values at the points of a lattice layer: `out[i + xs.len()·j] = f((xs[i], ys[j], z))`,
    /// `out.len()` being `xs.len()·ys.len()`. Grid polygonizers sample through it. The
    /// default evaluates the rows with [`Field::eval_many`]; a field whose terms depend on
    /// fewer axes (the compiled formulas) can compute those once per layer, row or column.
    /// The values must be [`Field::eval`]'s.
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        debug_assert_eq!(xs.len() * ys.len(), out.len());
        let mut points = Vec::with_capacity(xs.len());
        for (&y, row) in ys.iter().zip(out.chunks_mut(xs.len().max(1))) {
            points.clear();
            points.extend(xs.iter().map(|&x| DVec3::new(x, y, z)));
            self.eval_many(&points, row);
        }
    }

    /// A sampler of the layers of one lattice (`x` in `xs`, `y` in `ys`, any `z`), for
    /// callers that fill many layers: a field may do at its creation, once, the work that
    /// is the same on every layer (the compiled formulas compute their terms of `x` and `y`
    /// alone). The default samples each layer with [`Field::eval_layer`]. The values must
    /// be [`Field::eval`]'s.
    fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
        Box::new(EachLayer { field: self, xs: xs.to_vec(), ys: ys.to_vec() })
    }

    /// The gradient at one point. The default takes central differences with step
    /// [`Field::gradient_step`]; fields with a closed form should override it.
    fn gradient(&self, p: DVec3) -> DVec3 {
        let h = self.gradient_step();
        let d = |e: DVec3| (self.eval(p + e * h) - self.eval(p - e * h)) / (2.0 * h);
        DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z))
    }

    /// Values and gradients at many points.
    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        debug_assert_eq!(points.len(), values.len());
        debug_assert_eq!(points.len(), grads.len());
        self.eval_many(points, values);
        for (p, g) in points.iter().zip(grads.iter_mut()) {
            *g = self.gradient(*p);
        }
    }

    /// Whether the field gives its surface a colour ([`Field::colors_many`]): a skeleton
    /// whose elements have colours (DIS ch. 6). Polygonizers that evaluate the field next to
    /// each vertex anyway ask for the colour in the same evaluation
    /// ([`Field::eval_grad_color_many`]) only where this is true.
    fn has_colors(&self) -> bool {
        false
    }

    /// The surface colour (sRGB in `[0, 1]`) at each point into `colors`, and `true`; or
    /// `false`, writing nothing, for a field without colours (the default). A point's colour
    /// is its own, whatever the batch.
    fn colors_many(&self, points: &[DVec3], colors: &mut [[f32; 3]]) -> bool {
        let _ = (points, colors);
        false
    }

    /// [`Field::eval_grad_many`] and [`Field::colors_many`] at the same points; returns
    /// whether colours were written. The values and gradients must be
    /// [`Field::eval_grad_many`]'s, bit for bit, so that asking for colours never moves a
    /// vertex. Why one call: a skeleton's colour weights are its elements' densities, which
    /// the value sums anyway, so a field may give the colours for almost nothing (the
    /// default makes the two calls).
    fn eval_grad_color_many(
        &self,
        points: &[DVec3],
        values: &mut [f64],
        grads: &mut [DVec3],
        colors: &mut [[f32; 3]],
    ) -> bool {
        self.eval_grad_many(points, values, grads);
        self.colors_many(points, colors)
    }

    /// Step for finite-difference gradients. Polygonizers do not change it; fields that
    /// know their own scale may.
    fn gradient_step(&self) -> f64 {
        1e-5
    }

    /// Whether [`Field::gradient`] is exact (analytic or automatic differentiation) rather
    /// than a finite difference. Reported in statistics; never changes results.
    fn has_exact_gradient(&self) -> bool {
        false
    }

    /// A box known to hold the whole surface, when the field knows one.
    fn bounds(&self) -> Option<Aabb> {
        None
    }
}

/// Smart pointers and references to fields are fields.
macro_rules! forward_field {
    ($($ty:ty),*) => {$(
        impl<F: Field + ?Sized> Field for $ty {
            fn eval(&self, p: DVec3) -> f64 {
                (**self).eval(p)
            }
            fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
                (**self).eval_many(points, out)
            }
            fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
                (**self).eval_layer(xs, ys, z, out)
            }
            fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
                (**self).sampler(xs, ys)
            }
            fn gradient(&self, p: DVec3) -> DVec3 {
                (**self).gradient(p)
            }
            fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
                (**self).eval_grad_many(points, values, grads)
            }
            fn has_colors(&self) -> bool {
                (**self).has_colors()
            }
            fn colors_many(&self, points: &[DVec3], colors: &mut [[f32; 3]]) -> bool {
                (**self).colors_many(points, colors)
            }
            fn eval_grad_color_many(
                &self,
                points: &[DVec3],
                values: &mut [f64],
                grads: &mut [DVec3],
                colors: &mut [[f32; 3]],
            ) -> bool {
                (**self).eval_grad_color_many(points, values, grads, colors)
            }
            fn gradient_step(&self) -> f64 {
                (**self).gradient_step()
            }
            fn has_exact_gradient(&self) -> bool {
                (**self).has_exact_gradient()
            }
            fn bounds(&self) -> Option<Aabb> {
                (**self).bounds()
            }
        }
    )*};
}

forward_field!(&F, Box<F>, std::sync::Arc<F>);

/// Values on the layers of one lattice, from [`Field::sampler`]; shared by the threads that
/// sample the layers.
pub trait LayerSampler: Send + Sync {
    /// The values at rows `rows` of the layer at `z`: `out[i + nx·(j − rows.start)]` is the
    /// value at `(xs[i], ys[j], z)` for `j` in `rows` (`out.len()` = `nx·rows.len()`).
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]);
}

/// [`Field::sampler`]'s default: [`Field::eval_layer`] on each layer.
struct EachLayer<'a, F: ?Sized> {
    field: &'a F,
    xs: Vec<f64>,
    ys: Vec<f64>,
}

impl<F: Field + ?Sized> LayerSampler for EachLayer<'_, F> {
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]) {
        self.field.eval_layer(&self.xs, &self.ys[rows], z, out)
    }
}

/// Another sampler's values, each changed by a function (for [`Iso`] and [`Negate`]).
struct MapSampler<'a, M> {
    inner: Box<dyn LayerSampler + 'a>,
    map: M,
}

impl<M: Fn(f64) -> f64 + Send + Sync> LayerSampler for MapSampler<'_, M> {
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]) {
        self.inner.layer(z, rows, out);
        out.iter_mut().for_each(|v| *v = (self.map)(*v));
    }
}

/// A field from a closure, for tests and quick experiments.
///
/// ```
/// use skelform_field::{Field, FnField};
/// use glam::DVec3;
/// let sphere = FnField(|p: DVec3| p.length() - 1.0);
/// assert!(sphere.eval(DVec3::ZERO) < 0.0);
/// ```
#[derive(Clone, Copy)]
pub struct FnField<F>(pub F);

impl<F: Fn(DVec3) -> f64 + Send + Sync> Field for FnField<F> {
    fn eval(&self, p: DVec3) -> f64 {
        (self.0)(p)
    }
}

/// `f − c`: the level set `f = c` as the zero set.
#[derive(Clone, Copy, Debug)]
pub struct Iso<F> {
    /// The field whose level set is wanted.
    pub field: F,
    /// The level `c`, subtracted from every value; gradients are the field's own.
    pub iso: f64,
}

impl<F: Field> Field for Iso<F> {
    fn eval(&self, p: DVec3) -> f64 {
        self.field.eval(p) - self.iso
    }
    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        self.field.eval_many(points, out);
        out.iter_mut().for_each(|v| *v -= self.iso);
    }
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        self.field.eval_layer(xs, ys, z, out);
        out.iter_mut().for_each(|v| *v -= self.iso);
    }
    fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
        let iso = self.iso;
        Box::new(MapSampler { inner: self.field.sampler(xs, ys), map: move |v| v - iso })
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        self.field.gradient(p)
    }
    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        self.field.eval_grad_many(points, values, grads);
        values.iter_mut().for_each(|v| *v -= self.iso);
    }
    fn gradient_step(&self) -> f64 {
        self.field.gradient_step()
    }
    fn has_exact_gradient(&self) -> bool {
        self.field.has_exact_gradient()
    }
    fn bounds(&self) -> Option<Aabb> {
        None
    }
}

/// `−f`: turns a density that is larger inside into the inside-negative convention.
#[derive(Clone, Copy, Debug)]
pub struct Negate<F>(pub F);

impl<F: Field> Field for Negate<F> {
    fn eval(&self, p: DVec3) -> f64 {
        -self.0.eval(p)
    }
    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        self.0.eval_many(points, out);
        out.iter_mut().for_each(|v| *v = -*v);
    }
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        self.0.eval_layer(xs, ys, z, out);
        out.iter_mut().for_each(|v| *v = -*v);
    }
    fn sampler<'a>(&'a self, xs: &[f64], ys: &[f64]) -> Box<dyn LayerSampler + 'a> {
        Box::new(MapSampler { inner: self.0.sampler(xs, ys), map: |v: f64| -v })
    }
    fn gradient(&self, p: DVec3) -> DVec3 {
        -self.0.gradient(p)
    }
    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        self.0.eval_grad_many(points, values, grads);
        values.iter_mut().for_each(|v| *v = -*v);
        grads.iter_mut().for_each(|g| *g = -*g);
    }
    fn gradient_step(&self) -> f64 {
        self.0.gradient_step()
    }
    fn has_exact_gradient(&self) -> bool {
        self.0.has_exact_gradient()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_gradient_is_close_to_analytic() {
        let f = FnField(|p: DVec3| p.length_squared() - 1.0);
        let p = DVec3::new(0.3, -0.4, 0.5);
        let g = f.gradient(p);
        assert!((g - 2.0 * p).length() < 1e-6, "{g}");
    }

    #[test]
    fn iso_and_negate_adapters() {
        let density = FnField(|p: DVec3| 1.0 - p.length_squared());
        let f = Negate(Iso { field: density, iso: 0.75 });
        // density 0.75 at r = 0.5: surface there, inside negative.
        assert!(f.eval(DVec3::ZERO) < 0.0);
        assert!(f.eval(DVec3::new(0.5, 0.0, 0.0)).abs() < 1e-12);
        assert!(f.eval(DVec3::new(0.9, 0.0, 0.0)) > 0.0);
        let g = f.gradient(DVec3::new(0.5, 0.0, 0.0));
        assert!(g.x > 0.0, "outward normal points away from the centre");
        let mut v = [0.0; 2];
        let mut gs = [DVec3::ZERO; 2];
        f.eval_grad_many(&[DVec3::ZERO, DVec3::X], &mut v, &mut gs);
        assert_eq!(v[0], f.eval(DVec3::ZERO));
        assert!(gs[1].x > 0.0);
    }
}
