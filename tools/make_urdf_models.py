"""Write lagrax's example robot URDFs (``lagrax/models/urdf/*.urdf``) from simple solids.

Every link is a homogeneous solid of aluminium (density 2700 kg/m³): a circular cylinder
(radius r, length L) or a box (edges a, b, c). Mass ``m = ρ V``; inertia about the centre
of mass (``lagrax.bodies.cylinder_inertia``, ``box_inertia``):

- cylinder about its own axis ``m r²/2``, about a diameter ``m (3 r² + L²)/12``;
- box ``m/12 diag(b² + c², a² + c², a² + b²)``.

Run ``python tools/make_urdf_models.py`` to regenerate; the numbers are written with 9
significant digits.
"""

import math
from pathlib import Path

RHO = 2700.0  # aluminium, kg/m³
OUT = Path(__file__).resolve().parents[1] / "lagrax" / "models" / "urdf"


def f(x):
    return f"{x:.9g}"


def cylinder(r, length, axis="z"):
    m = RHO * math.pi * r**2 * length
    along, across = m * r**2 / 2, m * (3 * r**2 + length**2) / 12
    d = {k: across for k in "xyz"}
    d[axis] = along
    return m, d["x"], d["y"], d["z"]


def box(a, b, c):
    m = RHO * a * b * c
    return m, m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12


def inertial(solid, xyz, rpy="0 0 0", note=""):
    m, ixx, iyy, izz = solid
    return (
        f"    <inertial>  <!-- {note}: m = {f(m)} kg -->\n"
        f'      <origin xyz="{xyz}" rpy="{rpy}"/>\n'
        f'      <mass value="{f(m)}"/>\n'
        f'      <inertia ixx="{f(ixx)}" ixy="0" ixz="0" iyy="{f(iyy)}" iyz="0" izz="{f(izz)}"/>\n'
        "    </inertial>\n"
    )


def link(name, body="", mesh=None):
    visual = ""
    if mesh:  # geometry is ignored by lagrax: the mesh file does not exist
        visual = (
            f'    <visual><geometry><mesh filename="package://lagrax_models/meshes/{mesh}"/>'
            "</geometry></visual>\n"
        )
    return f'  <link name="{name}">\n{body}{visual}  </link>\n'


def joint(name, kind, parent, child, xyz, rpy="0 0 0", axis=None, limit=None, damping=None):
    s = f'  <joint name="{name}" type="{kind}">\n'
    s += f'    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
    s += f'    <origin xyz="{xyz}" rpy="{rpy}"/>\n'
    if axis:
        s += f'    <axis xyz="{axis}"/>\n'
    if limit:
        lo, hi, effort, vel = limit
        s += f'    <limit lower="{lo}" upper="{hi}" effort="{effort}" velocity="{vel}"/>\n'
    if damping is not None:
        s += f'    <dynamics damping="{damping}" friction="0.0"/>\n'
    return s + "  </joint>\n"


def arm7():
    # (name, radius, length, axis, limit, damping): link i is a cylinder along its z axis
    # from joint i to joint i + 1; joints alternate z (roll) and y (pitch) axes.
    spec = [
        ("link1", 0.060, 0.20, "0 0 1", (-2.96, 2.96, 176, 1.71), 0.5),
        ("link2", 0.060, 0.20, "0 1 0", (-2.09, 2.09, 176, 1.71), 0.5),
        ("link3", 0.050, 0.20, "0 0 1", (-2.96, 2.96, 110, 1.75), 0.3),
        ("link4", 0.050, 0.20, "0 -1 0", (-2.09, 2.09, 110, 2.27), 0.3),
        ("link5", 0.040, 0.18, "0 0 1", (-2.96, 2.96, 40, 2.44), 0.1),
        ("link6", 0.040, 0.08, "0 1 0", (-2.09, 2.09, 40, 3.14), 0.1),
        ("link7", 0.040, 0.04, "0 0 1", (-3.05, 3.05, 40, 3.14), 0.05),
    ]
    out = [
        '<?xml version="1.0"?>\n',
        "<!-- A 7-DOF arm written for lagrax (tools/make_urdf_models.py). Links are solid\n"
        "     aluminium (2700 kg/m3) cylinders along their z axes: m = rho pi r^2 L,\n"
        "     I = m r^2/2 about the axis, m (3 r^2 + L^2)/12 about a diameter. The gripper is\n"
        "     a solid aluminium box on a fixed joint; tool0 is a massless frame. -->\n",
        '<robot name="lagrax_arm7">\n',
        link(
            "base_link",
            inertial(cylinder(0.08, 0.15), "0 0 0.075", note="cylinder r=0.08 L=0.15"),
            "base.stl",
        ),
    ]
    parent, height = "base_link", 0.15
    for i, (name, r, length, axis, limit, damping) in enumerate(spec):
        out.append(
            joint(
                f"joint{i + 1}",
                "revolute",
                parent,
                name,
                f"0 0 {height}",
                axis=axis,
                limit=limit,
                damping=damping,
            )
        )
        if name == "link4":
            # the same cylinder described along x in a rotated inertial frame: URDF's
            # <inertial><origin rpy> (pitch -pi/2 turns x into z)
            body = inertial(
                cylinder(r, length, axis="x"),
                f"0 0 {length / 2}",
                rpy="0 -1.57079632679 0",
                note=f"cylinder r={r} L={length}, along x",
            )
        else:
            body = inertial(
                cylinder(r, length), f"0 0 {length / 2}", note=f"cylinder r={r} L={length}"
            )
        out.append(link(name, body, f"{name}.stl"))
        parent, height = name, length
    out.append(
        joint("gripper_mount", "fixed", "link7", "gripper", "0 0 0.04", rpy="0 0 0.785398163")
    )
    out.append(
        link("gripper", inertial(box(0.08, 0.06, 0.10), "0 0 0.05", note="box 0.08 x 0.06 x 0.10"))
    )
    out.append(joint("tool0_joint", "fixed", "gripper", "tool0", "0 0 0.10"))
    out.append(link("tool0"))
    out.append("</robot>\n")
    return "".join(out)


def torso_two_arms():
    out = [
        '<?xml version="1.0"?>\n',
        "<!-- A small tree written for lagrax (tools/make_urdf_models.py): a torso on a\n"
        "     prismatic lift and a yaw joint, carrying a fixed head and two 3-link arms\n"
        "     (shoulder pitch, shoulder roll, elbow; the right elbow is continuous). Solid\n"
        "     aluminium (2700 kg/m3) boxes and cylinders; see the comments for each. -->\n",
        '<robot name="lagrax_torso_two_arms">\n',
        link("world"),
        joint(
            "lift",
            "prismatic",
            "world",
            "pelvis",
            "0 0 0.5",
            axis="0 0 1",
            limit=(-0.2, 0.2, 500, 0.5),
            damping=2.0,
        ),
        link("pelvis", inertial(box(0.20, 0.30, 0.10), "0 0 0", note="box 0.20 x 0.30 x 0.10")),
        joint(
            "torso_yaw",
            "revolute",
            "pelvis",
            "torso",
            "0 0 0.05",
            axis="0 0 1",
            limit=(-1.57, 1.57, 200, 1.5),
            damping=1.0,
        ),
        link("torso", inertial(box(0.15, 0.30, 0.40), "0 0 0.2", note="box 0.15 x 0.30 x 0.40")),
        joint("neck", "fixed", "torso", "head", "0.02 0 0.45", rpy="0 0.2 0"),
        link(
            "head",
            inertial(
                box(0.12, 0.10, 0.12), "0.01 0 0.06", rpy="0 0 0.3", note="box 0.12 x 0.10 x 0.12"
            ),
        ),
    ]
    for side, sign in (("left", 1), ("right", -1)):
        # the arm hangs down (-z) from a shoulder at the torso's top corner, turned by a
        # roll of +-0.3 rad so the two arms are mirror images
        upper, fore = cylinder(0.035, 0.28), cylinder(0.03, 0.25)
        out += [
            joint(
                f"{side}_shoulder_pitch",
                "revolute",
                "torso",
                f"{side}_shoulder",
                f"0 {sign * 0.19} 0.36",
                rpy=f"{sign * 0.3} 0 0",
                axis="0 1 0",
                limit=(-3.0, 1.0, 80, 2.0),
                damping=0.2,
            ),
            link(
                f"{side}_shoulder",
                inertial(
                    cylinder(0.04, 0.06, axis="y"), "0 0 0", note="cylinder r=0.04 L=0.06 along y"
                ),
            ),
            joint(
                f"{side}_shoulder_roll",
                "revolute",
                f"{side}_shoulder",
                f"{side}_upper_arm",
                "0 0 0",
                axis="1 0 0",
                limit=(-0.5, 2.5, 80, 2.0),
                damping=0.2,
            ),
            link(f"{side}_upper_arm", inertial(upper, "0 0 -0.14", note="cylinder r=0.035 L=0.28")),
            joint(
                f"{side}_elbow",
                "revolute" if side == "left" else "continuous",
                f"{side}_upper_arm",
                f"{side}_forearm",
                "0 0 -0.28",
                axis="0 1 0",
                limit=(-2.5, 0.0, 40, 3.0) if side == "left" else (0, 0, 40, 3.0),
                damping=0.1,
            ),
            link(f"{side}_forearm", inertial(fore, "0 0 -0.125", note="cylinder r=0.03 L=0.25")),
        ]
    out.append("</robot>\n")
    return "".join(out)


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "arm7.urdf").write_text(arm7())
    (OUT / "torso_two_arms.urdf").write_text(torso_two_arms())
    print("wrote", OUT / "arm7.urdf", OUT / "torso_two_arms.urdf")
