// The environment light: render::environment and render::trig, operation for operation.
// The map's texels (one vec4 each) and its CDFs (four floats a vec4) lie in the texel
// buffer from params.env_texels and params.env_cdf; params.env_width 0: uniform.

// trig::sin_cos_turns: (sin, cos) of t turns.
fn sin_cos_turns(t: f32) -> vec2<f32> {
    let t4 = 4.0 * t;
    let q = floor(t4 + 0.5);
    let a = (t4 - q) * FRAC_PI_2;
    let a2 = a * a;
    let s = a + a * a2 * (SIN_C1 + a2 * (SIN_C2 + a2 * (SIN_C3 + a2 * SIN_C4)));
    let c = 1.0 + a2 * (COS_C1 + a2 * (COS_C2 + a2 * (COS_C3 + a2 * COS_C4)));
    switch i32(q) & 3 {
        case 0: { return vec2<f32>(s, c); }
        case 1: { return vec2<f32>(c, -s); }
        case 2: { return vec2<f32>(-s, -c); }
        default: { return vec2<f32>(-c, s); }
    }
}

// trig::atan2_turns: the angle of (x, y) in turns.
fn atan2_turns(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let hi = max(ax, ay);
    if hi == 0.0 {
        return 0.0;
    }
    let a = min(ax, ay) / hi;
    let s = a * a;
    var r = a * (ATAN_C0 + s * (ATAN_C1 + s * (ATAN_C2 + s * (ATAN_C3 + s * (ATAN_C4 + s * ATAN_C5)))));
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        r = -r;
    }
    return r * INV_TAU;
}

fn env_cdf_at(k: u32) -> f32 {
    return texel(params.env_cdf + k / 4u)[k % 4u];
}

fn env_texel(i: u32, j: u32) -> vec3<f32> {
    return texel(params.env_texels + j * params.env_width + i).xyz;
}

// environment::find: the cell u falls in among n from entry `base` of the CDFs.
fn env_find(base: u32, n: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = n - 1u;
    while lo < hi {
        let mid = (lo + hi + 1u) / 2u;
        if env_cdf_at(base + mid) <= u {
            lo = mid;
        } else {
            hi = mid - 1u;
        }
    }
    return lo;
}

// Environment::local
fn env_local(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot3(params.env_x, d), dot3(params.env_y, d), dot3(params.env_z, d));
}

// EnvMap::coords: (x, y, sin θ).
fn env_coords(l: vec3<f32>) -> vec3<f32> {
    let w = f32(params.env_width);
    let rows = f32(params.env_height - 1u);
    var u = atan2_turns(l.x, -l.z);
    if u < 0.0 {
        u += 1.0;
    }
    let sin_theta = sqrt(l.x * l.x + l.z * l.z);
    let v = 2.0 * atan2_turns(sin_theta, l.y);
    var x = u * w - 0.5;
    if x < 0.0 {
        x += w;
    }
    return vec3<f32>(x, v * rows, sin_theta);
}

// EnvMap::cell
fn env_cell(x: f32, y: f32) -> vec2<u32> {
    return vec2<u32>(min(u32(floor(x)), params.env_width - 1u), min(u32(floor(y)), params.env_height - 2u));
}

// EnvMap::cell_probability
fn env_cell_probability(c: vec2<u32>) -> f32 {
    let base = params.env_height + c.y * (params.env_width + 1u);
    return (env_cdf_at(c.y + 1u) - env_cdf_at(c.y)) * (env_cdf_at(base + c.x + 1u) - env_cdf_at(base + c.x));
}

// Environment::eval: the radiance seen looking along the unit direction d.
fn env_eval(d: vec3<f32>) -> vec3<f32> {
    if params.env_width == 0u {
        return params.env_radiance;
    }
    let xy = env_coords(env_local(d));
    let c = env_cell(xy.x, xy.y);
    let tx = xy.x - f32(c.x);
    let ty = xy.y - f32(c.y);
    let i1 = (c.x + 1u) % params.env_width;
    let a = env_texel(c.x, c.y);
    let b = env_texel(i1, c.y);
    let cc = env_texel(c.x, c.y + 1u);
    let dd = env_texel(i1, c.y + 1u);
    let top = a + (b - a) * tx;
    let bottom = cc + (dd - cc) * tx;
    return params.env_radiance * (top + (bottom - top) * ty);
}

// Environment::pdf
fn env_pdf(d: vec3<f32>) -> f32 {
    if params.env_width == 0u {
        return UNIFORM_SPHERE_PDF;
    }
    let xy = env_coords(env_local(d));
    if !(xy.z > 0.0) {
        return 0.0;
    }
    let w = f32(params.env_width);
    let rows = f32(params.env_height - 1u);
    return env_cell_probability(env_cell(xy.x, xy.y)) * (w * rows) * MAP_PDF_SCALE / xy.z;
}

// Environment::sample: a direction (xyz) and its density (w; 0: none).
fn env_sample(u1: f32, u2: f32) -> vec4<f32> {
    if params.env_width == 0u {
        let y = 1.0 - 2.0 * u1;
        let r = sqrt(max(1.0 - y * y, 0.0));
        let sc = sin_cos_turns(u2);
        return vec4<f32>(r * sc.x, y, -r * sc.y, UNIFORM_SPHERE_PDF);
    }
    let w = f32(params.env_width);
    let rows = f32(params.env_height - 1u);
    let j = env_find(0u, params.env_height - 1u, u1);
    let p_row = env_cdf_at(j + 1u) - env_cdf_at(j);
    let dv = (u1 - env_cdf_at(j)) / p_row;
    let base = params.env_height + j * (params.env_width + 1u);
    let i = env_find(base, params.env_width, u2);
    let p_col = env_cdf_at(base + i + 1u) - env_cdf_at(base + i);
    let du = (u2 - env_cdf_at(base + i)) / p_col;
    var u = (f32(i) + du + 0.5) / w;
    if u >= 1.0 {
        u -= 1.0;
    }
    let v = (f32(j) + dv) / rows;
    let theta = sin_cos_turns(0.5 * v);
    if !(theta.x > 0.0) {
        return vec4<f32>(0.0);
    }
    let phi = sin_cos_turns(u);
    let l = vec3<f32>(phi.x * theta.x, theta.y, -phi.y * theta.x);
    let d = params.env_x * l.x + params.env_y * l.y + params.env_z * l.z;
    return vec4<f32>(d, p_row * p_col * (w * rows) * MAP_PDF_SCALE / theta.x);
}
