"""The default face's mouth in profile, chin, nose wings and tongue (issue 11).

Each test pins a fix as a measurable property of the mesh or its
deformation: a smooth tongue (the helper mesh refined by Catmull-Clark)
whose tip and body bend as a whole; lips that push out round (the artist's
pucker) instead of as a sheared slab; a chin that goes down without pulling
the lower lip's outline to a point; nostril wings that flare as a lobe.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.default import load_default_face
from realizer.face.deform import deform
from realizer.face.model import Face
from tests.face.test_lips import CORNER_SHARE, added_turning, lip_contours

#: the sheet's jaw opening for the tongue's rows (fap_sheet.csv)
JAW = {3: 900.0}


@pytest.fixture(scope="module")
def face() -> Face:
    return load_default_face()


def posed(face: Face, values: dict[int, float]) -> np.ndarray:
    vector = np.zeros(68)
    for fap, value in values.items():
        vector[fap - 1] = value
    return np.asarray(deform(face, vector), dtype=np.float64)


def tongue_triangles(face: Face) -> np.ndarray:
    faces = np.asarray(face.faces)
    result: np.ndarray = faces[np.isin(faces, face.part("tongue")).all(axis=1)]
    return result


def dihedral_degrees(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The angle between the normals of each pair of triangles sharing an edge."""
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    normals = np.cross(b - a, c - a)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    edges = np.sort(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1
    )
    owner = np.tile(np.arange(len(triangles)), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    shared = np.all(edges[1:] == edges[:-1], axis=1)
    first, second = owner[:-1][shared], owner[1:][shared]
    cosine = np.clip(np.sum(normals[first] * normals[second], axis=1), -1.0, 1.0)
    result: np.ndarray = np.degrees(np.arccos(cosine))
    return result


def test_the_tongue_is_a_smooth_closed_surface(face: Face) -> None:
    """hm08's helper tongue (224 quads) creased up to 112 degrees between
    neighbouring triangles and read as a faceted blob; refined once by
    Catmull-Clark it is a closed surface (every edge shared by two
    triangles) of 1792 triangles whose neighbours turn at most 65 degrees
    (95 % of them under 30)."""
    triangles = tongue_triangles(face)
    assert len(triangles) >= 1500
    angles = dihedral_degrees(np.asarray(face.vertices, dtype=np.float64), triangles)
    assert len(angles) == len(triangles) * 3 // 2  # closed: each edge has two sides
    assert angles.max() < 65.0
    assert np.percentile(angles, 95) < 30.0


@pytest.mark.parametrize(
    "fap, value", [(43, 128), (43, -128), (44, 512), (44, -512), (45, 300), (46, 512),
                   (46, -512), (47, 50000)]
)  # fmt: skip
def test_no_tongue_fap_creases_or_flips_the_tongue(face: Face, fap: int, value: float) -> None:
    """At the sheet's values (jaw open 900): no tongue triangle turns over
    and neighbours turn at most 80 degrees (the helper's spheres: 110+)."""
    triangles = tongue_triangles(face)
    before = posed(face, JAW)
    after = posed(face, {**JAW, fap: value})
    a0, b0, c0 = (before[triangles[:, k]] for k in range(3))
    a1, b1, c1 = (after[triangles[:, k]] for k in range(3))
    n0 = np.cross(b0 - a0, c0 - a0)
    n1 = np.cross(b1 - a1, c1 - a1)
    assert int(np.sum(np.sum(n0 * n1, axis=1) < 0.0)) == 0
    assert dihedral_degrees(after, triangles).max() < 80.0


@pytest.mark.parametrize(
    "fap, axis, unit", [(43, (-1.0, 0.0, 0.0), "mw"), (44, (0.0, 1.0, 0.0), "mns")]
)
def test_the_tongue_tip_bends_the_front_as_a_whole(
    face: Face, fap: int, axis: tuple[float, float, float], unit: str
) -> None:
    """6.1 moves one FAPU per unit along Table 7's axis; the root stays; the
    motion grows steadily from the root to the tip and every slice across
    the tongue moves alike (a sphere round 6.1 dented the front into a
    faceted hexagon)."""
    value = 200.0
    offsets = posed(face, {fap: value}) - np.asarray(face.vertices, dtype=np.float64)
    tongue = face.part("tongue")
    along_axis = offsets[tongue] @ np.asarray(axis)
    tip = offsets[face.feature_vertex("6.1")] @ np.asarray(axis)
    assert tip == pytest.approx(value * getattr(face.fapu, unit), rel=0.02)
    z = np.asarray(face.vertices, dtype=np.float64)[tongue, 2]
    root = z < z.min() + 0.25 * (z.max() - z.min())
    assert np.abs(along_axis[root]).max() < 0.01 * tip
    # a function of depth only: slices 0.5 mm deep move within 3 % of the tip
    for start in np.arange(z.min(), z.max(), 0.0005):
        in_slice = (z >= start) & (z < start + 0.0005)
        if in_slice.sum() > 1:
            assert np.ptp(along_axis[in_slice]) < 0.03 * tip
    means = [
        along_axis[(z >= s) & (z < s + 0.01)].mean()
        for s in np.arange(z.min(), z.max() - 0.01, 0.01)
    ]
    assert np.all(np.diff(means) >= -1e-6)


def test_raising_the_tongue_lifts_the_body_whole_without_a_notch(face: Face) -> None:
    """46 (both signs): the body and the tip rise alike, the root stays
    (the sphere round 6.2 left a V notch at the top's middle going down)."""
    tongue = face.part("tongue")
    v = np.asarray(face.vertices, dtype=np.float64)
    z = v[tongue, 2]
    for value in (512.0, -512.0):
        lift = (posed(face, {46: value}) - v)[tongue, 1]
        expected = value * face.fapu.mns
        front = z > z.min() + 0.5 * (z.max() - z.min())
        np.testing.assert_allclose(lift[front], expected, rtol=0.02)
        assert np.abs(lift[z < z.min() + 0.003]).max() < 0.05 * abs(expected)


@pytest.mark.parametrize("fap, point, edge", [(16, "2.3", "8.2"), (17, "2.2", "8.1")])
def test_a_pushed_lip_goes_out_round_not_as_a_slab(
    face: Face, fap: int, point: str, edge: str
) -> None:
    """Pushing a lip out (16, 17 positive) at 512 MNS: the inner midpoint
    goes straight forward 512 MNS and the lip's outer edge goes along at
    least 60 % of that (the lip field left it at 45 %: the front of the lip
    leaned into a slab with its contact face bared); the other lip stays,
    the chin (2.10) and the nose's base (9.15) move under 1.5 mm."""
    value = 512.0
    offsets = (posed(face, {fap: value}) - np.asarray(face.vertices, dtype=np.float64)) * 1000
    forward = value * face.fapu.mns * 1000
    np.testing.assert_allclose(offsets[face.feature_vertex(point)], [0.0, 0.0, forward], atol=0.05)
    assert offsets[face.feature_vertex(edge), 2] > 0.6 * forward
    other = "2.2" if point == "2.3" else "2.3"
    assert np.linalg.norm(offsets[face.feature_vertex(other)]) < 0.01
    for still in ("2.10", "9.15"):
        assert np.linalg.norm(offsets[face.feature_vertex(still)]) < 1.5, still


@pytest.mark.parametrize("value", [512.0, 800.0])
def test_the_dropped_upper_lip_laps_over_the_lower_one(face: Face, value: float) -> None:
    """lower_t_midlip (4) positive drops the upper lip's middle onto the
    lower lip: it also comes forward (0.3 mm per mm down, as 8+/9+), so
    its front, on the midline below the lips' contact, lies at least 2.5 mm
    ahead of the lower lip's front (straight down it was 1.2 mm at 512, the
    lip's edge tucked into the lower lip's front and folded there)."""
    v = np.asarray(face.vertices, dtype=np.float64)
    p = posed(face, {4: value})
    skin = face.part("skin")
    middle, lower_middle, lower_edge = (v[face.feature_vertex(n)] for n in ("2.2", "2.3", "8.2"))
    mid = skin[np.abs(v[skin, 0]) < 0.0008]
    lower_front = mid[
        (v[mid, 1] <= lower_middle[1])
        & (v[mid, 1] >= lower_edge[1])
        & (v[mid, 2] > lower_middle[2] - 0.001)
    ]
    upper_front = mid[(v[mid, 1] > lower_middle[1]) & (v[mid, 2] > middle[2])]
    dropped = upper_front[p[upper_front, 1] < lower_middle[1]]
    assert len(dropped) >= 2
    ahead = (p[dropped, 2].min() - v[lower_front, 2].max()) * 1000
    assert ahead > 2.5


def test_lowering_the_chin_leaves_the_lower_lip_round(face: Face) -> None:
    """18 at -512: the chin (2.10) goes down 512 MNS, the lower lip's outer
    contour stays (the sphere pulled 8.2 down 2.3 mm and 8.7/8.8 0.8 mm: a
    point in the middle); at +512 the chin still pushes the lip up."""
    v = np.asarray(face.vertices, dtype=np.float64)
    down = posed(face, {18: -512.0}) - v
    drop = 512 * face.fapu.mns
    assert -down[face.feature_vertex("2.10"), 1] == pytest.approx(drop, rel=0.02)
    for name in ("8.2", "8.7", "8.8", "2.3"):
        assert np.linalg.norm(down[face.feature_vertex(name)]) < 0.02 * drop, name
    up = posed(face, {18: 512.0}) - v
    assert up[face.feature_vertex("8.2"), 1] > 0.1 * drop


@pytest.mark.parametrize("fap, point, sign", [(61, "9.1", 1.0), (62, "9.2", -1.0)])
def test_a_nostril_wing_flares_as_a_lobe(face: Face, fap: int, point: str, sign: float) -> None:
    """At the sheet's 96 ENS the wing's skin within 6 mm of 9.1 (towards the
    nose's middle) moves out as far as 9.1 (it moved 37 % of that, so the
    flare barely showed), and the nostril's lower edge (9.5 / 9.4) at least
    half as far (it moved 17 %)."""
    v = np.asarray(face.vertices, dtype=np.float64)
    offsets = posed(face, {fap: 96.0}) - v
    wing = sign * offsets[face.feature_vertex(point), 0]
    assert wing == pytest.approx(96 * face.fapu.ens, rel=0.02)
    skin = face.part("skin")
    p = v[face.feature_vertex(point)]
    lobe = skin[(np.linalg.norm(v[skin] - p, axis=1) < 0.006) & (sign * (p[0] - v[skin, 0]) > 0)]
    assert lobe.size >= 5
    assert sign * offsets[lobe, 0].mean() > 0.9 * wing
    edge = "9.5" if sign > 0 else "9.4"
    assert sign * offsets[face.feature_vertex(edge), 0] > 0.5 * wing


def test_a_closed_outward_tongue_is_culled_an_open_or_inward_one_is_not(face: Face) -> None:
    """The renderer draws the refined tongue from outside only (back faces
    culled, as the skin's: its triangles must not cost twice); a tongue with
    a hole, or facing inwards, is drawn from both sides as before."""
    from realizer.face.render import closed_outward

    faces = np.asarray(face.faces)
    tongue = face.part("tongue")
    assert closed_outward(face.vertices, faces, tongue)
    mine = np.isin(faces, tongue).all(axis=1)
    holed = np.delete(faces, np.flatnonzero(mine)[0], axis=0)
    assert not closed_outward(face.vertices, holed, tongue)
    inward = faces.copy()
    inward[mine] = inward[mine][:, ::-1]
    assert not closed_outward(face.vertices, inward, tongue)


#: The most a vertex of the outer contour between the corners (within
#: test_lips' CORNER_SHARE of the corner's x) may turn under 51, 52 at 512,
#: degrees: the flat-topped profile turned the vertices at the flat's ends
#: by 40 (52+: a W), 31 (52-: a pouch), 23 (51+), 21 (51-: a dome).
OUTER_MIDDLE_MAX_TURN = 16.0


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+", "-"])
@pytest.mark.parametrize(
    "fap, point, contour", [(51, "8.1", "upper outer"), (52, "8.2", "lower outer")]
)
def test_the_outer_lip_middle_bends_its_outline_as_an_arch(
    face: Face, fap: int, point: str, contour: str, sign: float
) -> None:
    """51 and 52 at 512 MNS (the sheet's value): the feature point moves
    512 MNS, the lip corners stay, and the outline between them bends as an
    arch: no vertex of it turns by more than OUTER_MIDDLE_MAX_TURN (the
    turn shared out among hm08's few contour vertices, as test_lips pins
    for the inner line)."""
    v = np.asarray(face.vertices, dtype=np.float64)
    loop = lip_contours(face)[contour]
    p = posed(face, {fap: sign * 512.0})
    motion = (p - v)[face.feature_vertex(point), 1]
    assert abs(motion) == pytest.approx(512 * face.fapu.mns, rel=0.02)
    for name in ("8.3", "8.4"):
        assert np.linalg.norm((p - v)[face.feature_vertex(name)]) < 0.1 * abs(motion)
    added = np.abs(added_turning(face, loop, p))
    x = np.abs(v[loop[1:-1], 0])
    between = x < CORNER_SHARE * abs(float(v[loop[0], 0]))
    assert added[between].max() < OUTER_MIDDLE_MAX_TURN, f"{added[between].max():.1f} degrees"


@pytest.mark.parametrize("value", [256.0, -256.0])
def test_shifting_the_jaw_carries_the_lip_corners_half_way(face: Face, value: float) -> None:
    """At 256 MW (the practical range's end) the artist's jawRight slid the
    lower lip 13 mm under the still upper one, its end standing out past one
    corner (which went 62 % as far as the lip's middle, the other 39 %) with
    a kink beside each (skin stretched up to 0.9 mm per mm within 12 mm of
    a corner): now both inner corners (2.4, 2.5) go half as far as the
    lower lip's middle (2.3), which still goes with the chin, the skin round
    them stretches under 0.8 mm per mm, and the upper lip's middle (2.2)
    moves at most 15 % as far (the artist's jawRight drags it 12 %)."""
    v = np.asarray(face.vertices, dtype=np.float64)
    offsets = posed(face, {15: value}) - v
    middle = offsets[face.feature_vertex("2.3"), 0]
    chin = offsets[face.feature_vertex("2.1"), 0]
    assert abs(chin) == pytest.approx(abs(value) * face.fapu.mw, rel=0.02)
    assert middle / chin > 0.8
    skin = face.part("skin")
    faces = np.asarray(face.faces)
    faces = faces[np.isin(faces, skin).all(axis=1)]
    edges = np.unique(
        np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1),
        axis=0,
    )
    for corner in ("2.4", "2.5"):
        share = offsets[face.feature_vertex(corner), 0] / middle
        assert 0.45 < share < 0.55, corner
        p = v[face.feature_vertex(corner)]
        near = edges[(np.linalg.norm(v[edges] - p, axis=2) < 0.012).all(axis=1)]
        stretch = np.linalg.norm(
            offsets[near[:, 0]] - offsets[near[:, 1]], axis=1
        ) / np.linalg.norm(v[near[:, 0]] - v[near[:, 1]], axis=1)
        assert stretch.max() < 0.8, corner
    assert np.linalg.norm(offsets[face.feature_vertex("2.2")]) < 0.15 * abs(chin)


def test_the_teeth_coordinates_run_tooth_by_tooth_from_the_midline(face: Face) -> None:
    """The shader's teeth come from per-vertex coordinates: the position
    along the arch in teeth (the central incisor 0..1, growing with |x| on
    both sides alike) and the height above the incisal edge (+ upper, -
    lower, 0 at the edge)."""
    from realizer.face.render import surface_attributes

    extra = surface_attributes(face)[0]
    v = np.asarray(face.vertices)
    for part, sign in (("upper_teeth", 1.0), ("lower_teeth", -1.0)):
        idx = face.part(part)
        tooth, height = extra[idx, 2], extra[idx, 3]
        order = np.argsort(np.abs(v[idx, 0]))
        assert (np.diff(tooth[order]) >= -1e-4).all()
        assert tooth.min() < 0.2 and tooth.max() > 4.0
        assert (height * sign > 0).all()
        assert np.abs(height).min() < 0.01 and np.abs(height).max() > 4.0
        by_x = np.argsort(v[idx, 0])
        mirrored = np.interp(-v[idx, 0], v[idx, 0][by_x], tooth[by_x])
        assert np.abs(mirrored - tooth).max() < 0.2


#: An open mouth with the upper lip raised: the upper teeth show (sheet units).
TEETH_SHOWN = {3: 400.0, 4: -300.0, 5: -300.0}


def test_the_front_teeth_show_gaps_between_crowns_not_a_flat_slab(face: Face) -> None:
    """Across the upper front teeth, 2 mm above their edge, a front render
    has a dark dip between each pair of crowns (the slab before: one flat
    shade, no dip) and the crowns' faces vary in shade (rounded)."""
    from realizer.face.render import FaceRenderer, Framing, RenderUnavailableError

    v = posed(face, TEETH_SHOWN)
    upper = face.part("upper_teeth")
    try:
        renderer = FaceRenderer(
            face,
            480,
            300,
            framing=Framing.of_points(np.asarray(face.vertices)[face.part("teeth")], margin=0.12),
        )
    except RenderUnavailableError as error:
        pytest.skip(f"no OpenGL: {error}")
    with renderer:
        image = renderer.render(v).astype(np.float64).mean(axis=2)
        front = upper[np.abs(v[upper, 0]) < 0.012]
        edge = v[front, 1].min()
        z = v[front, 2].max()
        left, right = renderer.project(
            np.array([[-0.012, edge + 0.002, z], [0.012, edge + 0.002, z]])
        )
    row = image[round(float(left[1])), int(left[0]) : int(right[0])]
    lit = np.median(row)
    assert lit > 90, "the front teeth are hidden or black"
    dark = row < 0.7 * lit
    dips = int((dark[1:] & ~dark[:-1]).sum())
    assert dips >= 3, f"{dips} gaps across the four front teeth"
    crowns = row[~dark]
    assert np.ptp(crowns) > 15.0
