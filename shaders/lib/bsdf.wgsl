// How a surface scatters light: render::bsdf, operation for operation (Lambert, and
// glTF's metallic-roughness: GGX with Smith's height-correlated visibility and Schlick's
// Fresnel over a Lambert base, sampled by the visible normals or the cosine).

// bsdf::Bsdf at one point: Diffuse(base) where `principled` is false.
struct Bsdf {
    base: vec3<f32>,
    metallic: f32,
    alpha: f32,
    principled: bool,
}

// bsdf::BsdfSample; pdf 0: none.
struct BsdfSample {
    dir: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
}

// sampling::basis: tangent and bitangent about unit n.
struct Basis {
    t: vec3<f32>,
    b: vec3<f32>,
}

fn basis(n: vec3<f32>) -> Basis {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let aa = -1.0 / (sign + n.z);
    let bb = n.x * n.y * aa;
    return Basis(vec3<f32>(1.0 + sign * n.x * n.x * aa, sign * bb, -sign * n.x),
                 vec3<f32>(bb, sign + n.y * n.y * aa, -n.y));
}

fn luminance(c: vec3<f32>) -> f32 {
    return c.x * LUMINANCE_R + c.y * LUMINANCE_G + c.z * LUMINANCE_B;
}

// bsdf::schlick_weight
fn schlick_weight(c: f32) -> f32 {
    let m = max(1.0 - c, 0.0);
    let m2 = m * m;
    return m2 * m2 * m;
}

// Principled::new
fn principled(base: vec3<f32>, metallic: f32, roughness: f32) -> Bsdf {
    let r = clamp(roughness, 0.0, 1.0);
    return Bsdf(clamp(base, vec3<f32>(0.0), vec3<f32>(1.0)), clamp(metallic, 0.0, 1.0),
                max(r * r, ALPHA_MIN), true);
}

// Principled::f0
fn principled_f0(b: Bsdf) -> vec3<f32> {
    return vec3<f32>(DIELECTRIC_F0) * (1.0 - b.metallic) + b.base * b.metallic;
}

// Principled::specular_probability
fn specular_probability(b: Bsdf, co: f32) -> f32 {
    let m5 = schlick_weight(co);
    let f0 = principled_f0(b);
    let fs = luminance(f0 + (vec3<f32>(1.0) - f0) * m5);
    let fd = (1.0 - b.metallic) * (1.0 - (DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * m5))
        * luminance(b.base);
    if fs + fd > 0.0 {
        return fs / (fs + fd);
    }
    return 1.0;
}

// Principled::eval: (f·cos θi, pdf).
fn principled_eval(b: Bsdf, n: vec3<f32>, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    let co = dot3(n, wo);
    let ci = dot3(n, wi);
    if co <= 0.0 || ci <= 0.0 {
        return vec4<f32>(0.0);
    }
    let h = normalize3(wo + wi);
    let noh = dot3(n, h);
    let voh = dot3(wo, h);
    let nh = cross3(n, h);
    let sin2 = dot3(nh, nh);
    let a2 = b.alpha * b.alpha;
    let k = noh * noh * a2 + sin2;
    let d = a2 / (PI * k * k);
    let vis = 0.5 / (ci * sqrt(co * co * (1.0 - a2) + a2) + co * sqrt(ci * ci * (1.0 - a2) + a2));
    let m5 = schlick_weight(voh);
    let f0 = principled_f0(b);
    let fresnel = f0 + (vec3<f32>(1.0) - f0) * m5;
    let kd = (1.0 - b.metallic) * (1.0 - (DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * m5));
    let f = fresnel * (d * vis) + b.base * (kd * PI_INV);
    let g1 = 2.0 * co / (co + sqrt(a2 + (1.0 - a2) * co * co));
    let spec_pdf = g1 * d / (4.0 * co);
    let ps = specular_probability(b, co);
    return vec4<f32>(f * ci, ps * spec_pdf + (1.0 - ps) * ci * PI_INV);
}

// Principled::visible_normal
fn visible_normal(b: Bsdf, n: vec3<f32>, wo: vec3<f32>, u1: f32, u2: f32) -> vec3<f32> {
    let f = basis(n);
    let a = b.alpha;
    let vh = normalize3(vec3<f32>(a * dot3(wo, f.t), a * dot3(wo, f.b), max(dot3(wo, n), 0.0)));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3<f32>(1.0, 0.0, 0.0);
    if lensq > 0.0 {
        let l = sqrt(lensq);
        t1 = vec3<f32>(-vh.y / l, vh.x / l, 0.0);
    }
    let t2 = cross3(vh, t1);
    let r = sqrt(u1);
    let sc = sin_cos_turns(u2);
    let p1 = r * sc.y;
    let sh = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - sh) * sqrt(max(1.0 - p1 * p1, 0.0)) + sh * (r * sc.x);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    let ne = normalize3(vec3<f32>(a * nh.x, a * nh.y, max(nh.z, 0.0)));
    return f.t * ne.x + f.b * ne.y + n * ne.z;
}

// Bsdf::eval
fn bsdf_eval(b: Bsdf, n: vec3<f32>, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    if b.principled {
        return principled_eval(b, n, wo, wi);
    }
    let c = dot3(n, wi);
    if c <= 0.0 {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(b.base * (c * PI_INV), c * PI_INV);
}

// Bsdf::sample
fn bsdf_sample(b: Bsdf, n: vec3<f32>, wo: vec3<f32>) -> BsdfSample {
    if !b.principled {
        let dir = cosine_direction(n);
        return BsdfSample(dir, b.base, dot3(n, dir) * PI_INV);
    }
    var dir: vec3<f32>;
    if next_f32() < specular_probability(b, dot3(n, wo)) {
        let u1 = next_f32();
        let u2 = next_f32();
        let h = visible_normal(b, n, wo, u1, u2);
        dir = normalize3(h * (2.0 * dot3(wo, h)) - wo);
    } else {
        dir = cosine_direction(n);
    }
    let e = principled_eval(b, n, wo, dir);
    if e.w > 0.0 {
        return BsdfSample(dir, e.xyz / e.w, e.w);
    }
    return BsdfSample(dir, vec3<f32>(0.0), 0.0);
}
