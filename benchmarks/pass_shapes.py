"""What pass shapes cost on this GL (llvmpipe), in copy passes of an S x S RGBA16F texture,
interleaved in one process: texel fetches with erf weights vs precomputed weights, bilinear
fetches, 2-D passes, MRT outputs, a half-resolution copy.

    PYTHONPATH=src python benchmarks/pass_shapes.py 1024
"""
import statistics, sys, time, os
import numpy as np
import moderngl
from dermis.gl.context import create_context

S = int(sys.argv[1]) if len(sys.argv) > 1 else 1024
ctx = create_context(None)
VS = """#version 450
void main(){ vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2); gl_Position = vec4(p*2.0-1.0,0,1);}"""
HDR = "#version 450\nuniform sampler2D uSource; uniform sampler2D uStretch; out vec4 f_color;\n"

def fs_copy():
    return HDR + "void main(){ f_color = texelFetch(uSource, ivec2(gl_FragCoord.xy), 0);}"

def fs_bilin_copy():
    return HDR + "void main(){ vec2 inv = 1.0/vec2(textureSize(uSource,0)); f_color = texture(uSource, (gl_FragCoord.xy+vec2(0.3,0.0))*inv);}"

ERF = """float erf_as(float x){ float s=sign(x); x=abs(x); float t=1.0/(1.0+0.3275911*x);
 float y=1.0-(((((1.061405429*t-1.453152027)*t)+1.421413741)*t-0.284496736)*t+0.254829592)*t*exp(-x*x); return s*y;}"""

def fs_fetch(n, mode):
    # mode: erf (per-tap erf weights from stretch), const (uniform weights), premult-const
    body = "ivec2 ip = ivec2(gl_FragCoord.xy); ivec2 imax = textureSize(uSource,0)-1;\n"
    if mode == "erf":
        body += "vec2 st = texelFetch(uStretch, ip, 0).xy; float sigma = 0.7*st.x; float inv = 1.0/(sigma*1.414); float edge = erf_as(0.5*inv);\n"
        body += "vec4 c = texelFetch(uSource, ip, 0); vec3 sum = c.rgb*c.a*edge; float sa = c.a*edge;\n"
        for j in range(1, n + 1):
            body += f"{{ float e = erf_as({j}.5*inv); float w = 0.5*(e-edge); edge=e; vec4 a = texelFetch(uSource, clamp(ip+ivec2({j},0),ivec2(0),imax),0); vec4 b = texelFetch(uSource, clamp(ip-ivec2({j},0),ivec2(0),imax),0); sum += w*(a.rgb*a.a+b.rgb*b.a); sa += w*(a.a+b.a);}}\n"
        body += "f_color = vec4(sa>1e-6? sum/sa : c.rgb, sa);"
    elif mode == "const":
        body += "vec4 c = texelFetch(uSource, ip, 0); vec4 sum = c*uW[0];\n"
        for j in range(1, n + 1):
            body += f"sum += uW[{j}]*(texelFetch(uSource, clamp(ip+ivec2({j},0),ivec2(0),imax),0)+texelFetch(uSource, clamp(ip-ivec2({j},0),ivec2(0),imax),0));\n"
        body += "f_color = sum;"
    elif mode == "bilin":  # n bilinear fetches per side at fractional offsets, plus centre
        body += "vec2 inv = 1.0/vec2(textureSize(uSource,0)); vec2 uv = gl_FragCoord.xy*inv; vec4 sum = texture(uSource, uv)*uW[0];\n"
        for j in range(1, n + 1):
            body += f"sum += uW[{j}]*(texture(uSource, uv+vec2(uO[{j}]*inv.x,0))+texture(uSource, uv-vec2(uO[{j}]*inv.x,0)));\n"
        body += "f_color = sum;"
    return HDR + "uniform float uW[16]; uniform float uO[16];\n" + ERF + "\nvoid main(){\n" + body + "}"

def fs_bilin2d(n):  # n x n bilinear fetches in one pass
    body = "vec2 inv = 1.0/vec2(textureSize(uSource,0)); vec2 uv = gl_FragCoord.xy*inv; vec4 sum = vec4(0);\n"
    for i in range(n):
        for j in range(n):
            body += f"sum += uW[{i}]*uW[{j}]*texture(uSource, uv+vec2(uO[{i}],uO[{j}])*inv);\n"
    return HDR + "uniform float uW[16]; uniform float uO[16];\nvoid main(){\n" + body + "f_color=sum;}"

def fs_mrt(k):
    outs = "".join(f"layout(location={i}) out vec4 o{i};\n" for i in range(k))
    body = "vec4 c = texelFetch(uSource, ivec2(gl_FragCoord.xy), 0);" + "".join(f"o{i}=c*{i+1}.0;" for i in range(k))
    return "#version 450\nuniform sampler2D uSource;\n" + outs + "void main(){" + body + "}"

rng = np.random.default_rng(0)
src = ctx.texture((S, S), 4, rng.random((S, S, 4)).astype(np.float16).tobytes(), dtype="f2")
src.filter = (moderngl.LINEAR, moderngl.LINEAR)
st = ctx.texture((S, S), 4, (1 + rng.random((S, S, 4))).astype(np.float32).tobytes(), dtype="f4")
dsts = [ctx.texture((S, S), 4, dtype="f2") for _ in range(4)]
fbo1 = ctx.framebuffer(color_attachments=[dsts[0]])
half = ctx.texture((S // 2, S // 2), 4, dtype="f2")
fboh = ctx.framebuffer(color_attachments=[half])

def mk(fs, k=1, fbo=None):
    p = ctx.program(vertex_shader=VS, fragment_shader=fs)
    if "uSource" in p: p["uSource"].value = 0
    if "uStretch" in p: p["uStretch"].value = 1
    if "uW" in p: p["uW"].value = [0.1] * p["uW"].array_length
    if "uO" in p: p["uO"].value = [1.3 + 2 * i for i in range(p["uO"].array_length)]
    vao = ctx.vertex_array(p, [])
    f = fbo or (fbo1 if k == 1 else ctx.framebuffer(color_attachments=dsts[:k]))
    def run():
        f.use(); src.use(0); st.use(1); vao.render(vertices=3)
    return run

cases = {"copy": mk(fs_copy()), "bilin_copy": mk(fs_bilin_copy())}
for n in (1, 2, 4, 6):
    cases[f"erf{n}"] = mk(fs_fetch(n, "erf"))
    cases[f"const{n}"] = mk(fs_fetch(n, "const"))
for n in (1, 2, 3, 4):
    cases[f"bilin{n}"] = mk(fs_fetch(n, "bilin"))
cases["bilin2d_2x2"] = mk(fs_bilin2d(2))
cases["bilin2d_3x3"] = mk(fs_bilin2d(3))
cases["mrt2"] = mk(fs_mrt(2), 2)
cases["mrt3"] = mk(fs_mrt(3), 3)
cases["copy_half"] = mk(fs_copy(), fbo=fboh)
for r in cases.values():
    r(); ctx.finish()
times = {k: [] for k in cases}
for rep in range(int(os.environ.get("REPS", 7))):
    for k, r in cases.items():
        ctx.finish(); t = time.perf_counter(); r(); ctx.finish(); times[k].append(time.perf_counter() - t)
c = statistics.median(times["copy"])
print(f"S={S} copy {c*1e3:.1f} ms load {os.getloadavg()[0]:.2f}")
for k, v in times.items():
    print(f"{k:14s} {statistics.median(v)/c:5.2f} copies")
