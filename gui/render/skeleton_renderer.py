"""Offscreen moderngl renderer: tennis court + one or two skeletons -> RGBA image.

Why offscreen (EGL standalone context rendering into a framebuffer, read back as pixels) rather than a
QOpenGLWidget: it works identically under ``QT_QPA_PLATFORM=offscreen``, under Xvfb and on a real display
(Mesa llvmpipe included), it needs no Qt at all (testable headless), and read-back at console sizes costs
about a millisecond. Bones are instanced cylinders and joints instanced spheres, so a whole skeleton is two
draw calls whatever its joint count."""
from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from gui.render.camera import OrbitCamera
from gui.render.court import COURT_LENGTH_M, DOUBLES_WIDTH_M, NET_HEIGHT_M, court_line_segments, net_segment, segments_to_quads
from gui.render.meshes import unit_cylinder, unit_sphere

_LIT_VS = """
#version 330
uniform mat4 u_vp;
in vec3 in_pos; in vec3 in_norm;
in vec3 i_a; in vec3 i_b; in float i_r; in vec3 i_color;
out vec3 v_norm; out vec3 v_color;
void main() {
    // i_b == i_a draws a sphere of radius i_r at i_a; otherwise a cylinder from i_a to i_b
    vec3 axis = i_b - i_a;
    float len = length(axis);
    vec3 w = len > 1e-6 ? axis / len : vec3(0.0, 0.0, 1.0);
    vec3 ref = abs(w.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 u = normalize(cross(ref, w));
    vec3 v = cross(w, u);
    float zs = len > 1e-6 ? len : i_r;
    vec3 p = i_a + (u * in_pos.x + v * in_pos.y) * i_r + w * in_pos.z * zs;
    v_norm = u * in_norm.x + v * in_norm.y + w * in_norm.z;
    v_color = i_color;
    gl_Position = u_vp * vec4(p, 1.0);
}
"""
_LIT_FS = """
#version 330
in vec3 v_norm; in vec3 v_color;
out vec4 f_color;
void main() {
    vec3 l = normalize(vec3(0.3, 1.0, 0.5));
    float d = abs(dot(normalize(v_norm), l));
    f_color = vec4(v_color * (0.5 + 0.5 * d), 1.0);
}
"""
_FLAT_VS = """
#version 330
uniform mat4 u_vp;
in vec3 in_pos; in vec3 in_color;
out vec3 v_color;
void main() { v_color = in_color; gl_Position = u_vp * vec4(in_pos, 1.0); }
"""
_FLAT_FS = """
#version 330
in vec3 v_color; out vec4 f_color;
void main() { f_color = vec4(v_color, 1.0); }
"""

BACKGROUND_RGB = (0.11, 0.12, 0.14)
SURROUND_RGB = (0.18, 0.36, 0.27)  # run-off area
COURT_RGB = (0.16, 0.33, 0.55)     # hard-court blue
LINE_RGB = (0.95, 0.95, 0.95)
NET_RGB = (0.85, 0.85, 0.80)


@dataclass(frozen=True, eq=False)
class SkeletonStyle:
    """Colours (linear 0-1 RGB) and sizes (metres) of one drawn skeleton."""

    bone_rgb: tuple[float, float, float]
    joint_rgb: tuple[float, float, float]
    bone_radius_m: float = 0.035
    joint_radius_m: float = 0.05
    # joint index -> colour for the bones of that joint's segment (e.g. a worn sensor's health)
    segment_rgb: dict[int, tuple[float, float, float]] | None = None


ESTIMATE_STYLE = SkeletonStyle(bone_rgb=(1.0, 0.55, 0.08), joint_rgb=(1.0, 0.75, 0.2))
TRUTH_STYLE = SkeletonStyle(bone_rgb=(0.2, 0.85, 0.9), joint_rgb=(0.55, 0.95, 1.0))


def bone_segments(positions_m: np.ndarray, parents: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(J,3) joint positions + parent indices (-1 = root) -> bone start/end points (B,3), (B,3) and each bone's
    parent joint (B,) — the joint whose segment the bone is (where a worn sensor's placement is anchored).

    Zero-length bones (e.g. a BVH root and hips sharing a point) are dropped."""
    parents = np.asarray(parents)
    child = np.flatnonzero(parents >= 0)
    a, b = positions_m[parents[child]], positions_m[child]
    keep = np.linalg.norm(b - a, axis=1) > 1e-4
    return a[keep], b[keep], parents[child][keep]


class SkeletonRenderer:
    """Owns a moderngl context + framebuffer; ``render`` returns an (H, W, 4) uint8 image, row 0 at the top."""

    def __init__(self, width_px: int = 960, height_px: int = 540, samples: int = 4,
                 ctx: moderngl.Context | None = None) -> None:
        self.ctx = ctx or moderngl.create_context(standalone=True, backend="egl")
        self.samples = samples
        self._lit = self.ctx.program(vertex_shader=_LIT_VS, fragment_shader=_LIT_FS)
        self._flat = self.ctx.program(vertex_shader=_FLAT_VS, fragment_shader=_FLAT_FS)
        self._cyl = self.ctx.buffer(unit_cylinder(12).tobytes())
        self._sph = self.ctx.buffer(unit_sphere(1).tobytes())
        self._cyl_n, self._sph_n = len(self._cyl.read()) // 24, len(self._sph.read()) // 24
        self._court = self._build_court()
        self._inst = self.ctx.buffer(reserve=4096 * 40, dynamic=True)  # grows on demand
        self._fbo = self._resolve = None
        self.resize(width_px, height_px)

    # -- setup -------------------------------------------------------------------------------------------
    def resize(self, width_px: int, height_px: int) -> None:
        width_px, height_px = max(16, int(width_px)), max(16, int(height_px))
        if self._fbo is not None and (width_px, height_px) == self.size:
            return
        old = [self._fbo] if self._resolve is self._fbo else [self._fbo, self._resolve]
        for fb in old:
            if fb is not None:
                for att in (*fb.color_attachments, fb.depth_attachment):
                    att.release()
                fb.release()
        self.size = (width_px, height_px)
        self._fbo = self.ctx.framebuffer(
            color_attachments=[self.ctx.renderbuffer(self.size, 4, samples=self.samples)],
            depth_attachment=self.ctx.depth_renderbuffer(self.size, samples=self.samples))
        self._resolve = (self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer(self.size, 4)],
                                              depth_attachment=self.ctx.depth_renderbuffer(self.size))
                         if self.samples else self._fbo)

    def _build_court(self) -> moderngl.VertexArray:
        """Static court geometry: surround, court surface, white lines (slightly raised), net band."""
        def quad(x0, z0, x1, z1, y, rgb):
            pts = np.array([[x0, z0], [x1, z0], [x1, z1], [x0, z0], [x1, z1], [x0, z1]])
            return np.c_[pts[:, 0], np.full(6, y), pts[:, 1], np.tile(rgb, (6, 1))]
        hl, hd = COURT_LENGTH_M / 2, DOUBLES_WIDTH_M / 2
        parts = [quad(-hd - 4, -hl - 6, hd + 4, hl + 6, -0.02, SURROUND_RGB),
                 quad(-hd - 1, -hl - 2, hd + 1, hl + 2, -0.01, COURT_RGB)]
        lines = segments_to_quads(court_line_segments())
        parts.append(np.c_[lines[:, 0], np.zeros(len(lines)), lines[:, 1], np.tile(LINE_RGB, (len(lines), 1))])
        (nx0, _), (nx1, _) = net_segment()
        net = np.array([[nx0, 0, 0], [nx1, 0, 0], [nx1, NET_HEIGHT_M, 0],
                        [nx0, 0, 0], [nx1, NET_HEIGHT_M, 0], [nx0, NET_HEIGHT_M, 0]])
        parts.append(np.c_[net, np.tile(NET_RGB, (6, 1))])
        data = np.concatenate(parts).astype("f4")
        return self.ctx.vertex_array(self._flat, [(self.ctx.buffer(data.tobytes()), "3f 3f", "in_pos", "in_color")])

    # -- drawing ----------------------------------------------------------------------------------------
    def _instances(self, skeletons: list[tuple[np.ndarray, np.ndarray, SkeletonStyle]]) -> tuple[np.ndarray, np.ndarray]:
        """Per-instance rows [a(3) b(3) r color(3)] for all bones and all joints of all skeletons."""
        bones, joints = [], []
        for pos, parents, style in skeletons:
            a, b, segment = bone_segments(pos, parents)
            rgb = np.tile(style.bone_rgb, (len(a), 1))
            for joint, colour in (style.segment_rgb or {}).items():
                rgb[segment == joint] = colour
            bones.append(np.c_[a, b, np.full(len(a), style.bone_radius_m), rgb])
            joints.append(np.c_[pos, pos, np.full(len(pos), style.joint_radius_m), np.tile(style.joint_rgb, (len(pos), 1))])
        empty = np.zeros((0, 10))
        return (np.concatenate(bones) if bones else empty).astype("f4"), (np.concatenate(joints) if joints else empty).astype("f4")

    def _draw_instanced(self, mesh: moderngl.Buffer, n_verts: int, inst: np.ndarray) -> None:
        if not len(inst):
            return
        data = inst.tobytes()
        if len(data) > self._inst.size:
            self._inst.release()
            self._inst = self.ctx.buffer(reserve=2 * len(data), dynamic=True)
        self._inst.write(data)
        vao = self.ctx.vertex_array(self._lit, [(mesh, "3f 3f", "in_pos", "in_norm"),
                                                (self._inst, "3f 3f 1f 3f/i", "i_a", "i_b", "i_r", "i_color")])
        vao.render(moderngl.TRIANGLES, vertices=n_verts, instances=len(inst))
        vao.release()

    def render(self, camera: OrbitCamera, skeletons: list[tuple[np.ndarray, np.ndarray, SkeletonStyle]]) -> np.ndarray:
        """Draw the court and each ``(positions (J,3) m, parents (J,), style)``; return (H, W, 4) uint8 RGBA."""
        w, h = self.size
        vp = camera.view_proj(w / h).T.astype("f4").tobytes()
        self._fbo.use()
        self.ctx.viewport = (0, 0, w, h)
        self.ctx.clear(*BACKGROUND_RGB, 1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self._flat["u_vp"].write(vp)
        self._lit["u_vp"].write(vp)
        self._court.render(moderngl.TRIANGLES)
        bones, joints = self._instances([(np.asarray(p, float), pa, s) for p, pa, s in skeletons])
        self._draw_instanced(self._cyl, self._cyl_n, bones)
        self._draw_instanced(self._sph, self._sph_n, joints)
        if self.samples:
            self.ctx.copy_framebuffer(self._resolve, self._fbo)
        raw = self._resolve.read(components=4, alignment=1)
        return np.frombuffer(raw, np.uint8).reshape(h, w, 4)[::-1]

    def release(self) -> None:
        self.ctx.release()
