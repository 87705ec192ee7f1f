"""Procedural low-poly models of object types, composed from primitives and sized to a type's typical box.

Each builder returns parts in the normalised box of :mod:`.primitives` (front +Z); :func:`procedural_model`
scales them to the requested size. Long thin objects lying on a surface (pens, cutlery, phones) are built
along Z and turned when their box is longer in X. The table :data:`BUILDERS` maps AI2-THOR object types
to builders; :func:`procedural_model` falls back to a plain box for an unknown type.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh

from .primitives import Part, assemble, ball, box, cylinder, lathe, ring, rod, turn

WOOD, DARK_WOOD, LIGHT_WOOD = (0.55, 0.37, 0.22), (0.34, 0.22, 0.13), (0.78, 0.62, 0.43)
WHITE, OFF_WHITE, PAPER = (0.93, 0.93, 0.92), (0.86, 0.84, 0.78), (0.96, 0.95, 0.9)
BLACK, DARK, GREY, METAL = (0.07, 0.07, 0.08), (0.22, 0.22, 0.24), (0.52, 0.53, 0.55), (0.74, 0.75, 0.78)
BLUE, GREY_FABRIC, BEIGE = (0.3, 0.42, 0.62), (0.52, 0.52, 0.55), (0.8, 0.72, 0.6)
RED, GREEN, LEAF, YELLOW = (0.8, 0.16, 0.12), (0.3, 0.6, 0.25), (0.2, 0.48, 0.2), (0.95, 0.82, 0.25)
ORANGE, BROWN, TERRACOTTA = (0.92, 0.47, 0.12), (0.45, 0.28, 0.15), (0.74, 0.4, 0.25)
GLASS, SCREEN, SILVER, CERAMIC = (0.7, 0.84, 0.88), (0.05, 0.07, 0.1), (0.82, 0.85, 0.88), (0.96, 0.96, 0.97)

Builder = Callable[[np.ndarray], list[Part]]


# --- furniture -------------------------------------------------------------------------------------------
def _legs(y1: float, w: float, rgb, inset: float = 0.03) -> list[Part]:
    a = 0.5 - inset - w
    return [box(x, 0, z, x + w, y1, z + w, rgb) for x in (-0.5 + inset, a) for z in (-0.5 + inset, a)]


def table(top=WOOD, legs=DARK_WOOD, thickness=0.07) -> Builder:
    return lambda s: [box(-0.5, 1 - thickness, -0.5, 0.5, 1, 0.5, top), *_legs(1 - thickness, 0.07, legs)]


def desk(s) -> list[Part]:
    parts = [box(-0.5, 0.93, -0.5, 0.5, 1, 0.5, WOOD),
             box(-0.49, 0, -0.48, -0.12, 0.93, 0.47, WOOD),  # drawer pedestal
             box(0.44, 0, -0.48, 0.49, 0.93, 0.47, WOOD),  # side panel
             box(-0.12, 0.45, -0.46, 0.44, 0.93, -0.42, DARK_WOOD)]  # modesty panel
    for i in range(3):
        y0 = 0.05 + i * 0.29
        parts += [box(-0.47, y0, 0.47, -0.14, y0 + 0.26, 0.5, LIGHT_WOOD),
                  box(-0.35, y0 + 0.11, 0.5, -0.26, y0 + 0.15, 0.52, METAL)]
    return parts


def side_table(s) -> list[Part]:
    return [box(-0.5, 0.93, -0.5, 0.5, 1, 0.5, WOOD), *_legs(0.93, 0.08, DARK_WOOD),
            box(-0.42, 0.72, -0.42, 0.42, 0.93, 0.45, WOOD), box(-0.08, 0.8, 0.45, 0.08, 0.85, 0.5, METAL),
            box(-0.45, 0.15, -0.45, 0.45, 0.2, 0.45, DARK_WOOD)]


def coffee_table(s) -> list[Part]:
    return [box(-0.5, 0.9, -0.5, 0.5, 1, 0.5, DARK_WOOD), *_legs(0.9, 0.07, DARK_WOOD),
            box(-0.45, 0.2, -0.45, 0.45, 0.26, 0.45, WOOD)]


def tv_stand(s) -> list[Part]:
    return [box(-0.5, 0.12, -0.5, 0.5, 1, 0.5, DARK_WOOD), box(-0.46, 0.2, 0.3, 0.46, 0.9, 0.51, BLACK),
            box(-0.01, 0.2, 0.3, 0.01, 0.9, 0.52, DARK_WOOD), *_legs(0.12, 0.06, BLACK)]


def counter_top(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.5, (0.8, 0.78, 0.74)), box(-0.5, 0, 0.46, 0.5, 0.3, 0.5, GREY)]


def chair(seat=WOOD, frame=DARK_WOOD) -> Builder:
    def build(s):
        return [*_legs(0.45, 0.07, frame), box(-0.5, 0.45, -0.5, 0.5, 0.52, 0.5, seat),
                box(-0.5, 0.52, -0.5, -0.42, 1, -0.42, frame), box(0.42, 0.52, -0.5, 0.5, 1, -0.42, frame),
                box(-0.45, 0.68, -0.5, 0.45, 0.97, -0.44, seat)]
    return build


def armchair(fabric=GREY_FABRIC, seats: int = 1) -> Builder:
    def build(s):
        parts = [box(-0.5, 0.06, -0.5, 0.5, 0.38, 0.5, fabric), box(-0.5, 0.38, -0.5, 0.5, 1, -0.22, fabric),
                 box(-0.5, 0.38, -0.22, -0.38, 0.65, 0.5, fabric), box(0.38, 0.38, -0.22, 0.5, 0.65, 0.5, fabric),
                 *_legs(0.06, 0.05, DARK_WOOD, inset=0.05)]
        width = 0.76 / seats
        for i in range(seats):
            x0 = -0.38 + i * width
            parts.append(box(x0 + 0.01, 0.38, -0.22, x0 + width - 0.01, 0.5, 0.48, BEIGE))
        return parts
    return build


def stool(s) -> list[Part]:
    return [cylinder(0, 0, 0.9, 1, 0.5, WOOD),
            *[rod((0.32 * np.cos(a), 0, 0.32 * np.sin(a)), (0.25 * np.cos(a), 0.9, 0.25 * np.sin(a)), 0.05, DARK_WOOD)
              for a in np.linspace(0, 2 * np.pi, 4, endpoint=False) + np.pi / 4],
            ring(0, 0.35, 0, 0.3, 0.025, METAL, axis=(0, 1, 0))]


def ottoman(s) -> list[Part]:
    return [box(-0.5, 0.12, -0.5, 0.5, 1, 0.5, BEIGE), box(-0.48, 0.85, -0.48, 0.48, 1, 0.48, OFF_WHITE),
            *_legs(0.12, 0.08, DARK_WOOD, inset=0.04)]


def bed(s) -> list[Part]:
    return [box(-0.5, 0.1, -0.5, 0.5, 0.32, 0.5, WOOD), box(-0.48, 0.32, -0.46, 0.48, 0.5, 0.48, WHITE),
            box(-0.49, 0.32, -0.1, 0.49, 0.53, 0.49, BLUE), box(-0.5, 0, -0.5, 0.5, 1, -0.45, DARK_WOOD),
            *_legs(0.1, 0.05, DARK_WOOD, inset=0.0),
            ball(-0.22, 0.56, -0.34, 0.2, OFF_WHITE, ry=0.06, rz=0.09),
            ball(0.22, 0.56, -0.34, 0.2, OFF_WHITE, ry=0.06, rz=0.09)]


def dog_bed(s) -> list[Part]:
    return [lathe([(0, 0), (0.5, 0), (0.5, 0.7), (0.42, 1), (0.36, 0.55), (0, 0.4)], BROWN),
            cylinder(0, 0, 0.35, 0.45, 0.36, BEIGE)]


def cabinet(body=WOOD, doors: int = 2) -> Builder:
    def build(s):
        parts = [box(-0.5, 0, -0.5, 0.5, 1, 0.46, body)]
        width = 1.0 / doors
        for i in range(doors):
            x0 = -0.5 + i * width
            parts += [box(x0 + 0.02, 0.03, 0.46, x0 + width - 0.02, 0.97, 0.5, LIGHT_WOOD)]
            hx = x0 + width - 0.12 if i % 2 == 0 else x0 + 0.08
            parts += [box(hx, 0.45, 0.5, hx + 0.04, 0.65, 0.53, METAL)]
        return parts
    return build


def drawer(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.85, 0.42, DARK_WOOD), box(-0.5, 0, 0.42, 0.5, 1, 0.5, LIGHT_WOOD),
            box(-0.15, 0.45, 0.5, 0.15, 0.6, 0.56, METAL)]


def dresser(s) -> list[Part]:
    parts = [box(-0.5, 0.05, -0.5, 0.5, 1, 0.46, WOOD), *_legs(0.05, 0.06, DARK_WOOD, inset=0.01)]
    for row in range(3):
        for col in range(2):
            x0, y0 = -0.48 + col * 0.49, 0.08 + row * 0.3
            parts += [box(x0, y0, 0.46, x0 + 0.47, y0 + 0.28, 0.5, LIGHT_WOOD),
                      ball(x0 + 0.235, y0 + 0.14, 0.52, 0.025, METAL)]
    return parts


def shelf(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.12, 0.5, LIGHT_WOOD), box(-0.5, 0, -0.5, 0.5, 1, -0.46, WOOD),
            box(-0.5, 0, -0.5, -0.47, 1, 0.5, WOOD), box(0.47, 0, -0.5, 0.5, 1, 0.5, WOOD)]


def shelving_unit(s) -> list[Part]:
    parts = [box(-0.5, 0, -0.5, -0.46, 1, 0.5, DARK_WOOD), box(0.46, 0, -0.5, 0.5, 1, 0.5, DARK_WOOD),
             box(-0.46, 0, -0.5, 0.46, 1, -0.47, WOOD)]
    parts += [box(-0.46, y, -0.47, 0.46, y + 0.03, 0.5, LIGHT_WOOD) for y in (0.02, 0.33, 0.64, 0.97)]
    return parts


def safe(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.45, DARK), box(-0.42, 0.08, 0.45, 0.42, 0.92, 0.5, GREY),
            ring(0.1, 0.55, 0.52, 0.1, 0.03, METAL),
            box(-0.3, 0.45, 0.5, -0.25, 0.65, 0.56, METAL)]


# --- appliances and electronics ---------------------------------------------------------------------------
def fridge(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.45, WHITE), box(-0.48, 0.62, 0.45, 0.48, 0.99, 0.5, OFF_WHITE),
            box(-0.48, 0.01, 0.45, 0.48, 0.6, 0.5, OFF_WHITE), box(0.36, 0.68, 0.5, 0.4, 0.9, 0.55, METAL),
            box(0.36, 0.35, 0.5, 0.4, 0.57, 0.55, METAL)]


def microwave(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.46, WHITE), box(-0.45, 0.12, 0.46, 0.2, 0.88, 0.5, SCREEN),
            box(0.25, 0.12, 0.46, 0.45, 0.88, 0.5, DARK), ball(0.35, 0.35, 0.5, 0.05, METAL)]


def toaster(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.95, 0.5, METAL), box(-0.35, 0.95, -0.3, 0.35, 1, -0.1, BLACK),
            box(-0.35, 0.95, 0.1, 0.35, 1, 0.3, BLACK), box(0.5, 0.6, -0.05, 0.5, 0.7, 0.05, BLACK)]


def coffee_machine(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.1, 0.5, BLACK), box(-0.5, 0, -0.5, 0.5, 1, -0.1, DARK),
            box(-0.5, 0.75, -0.1, 0.5, 1, 0.4, DARK), cylinder(0, 0.15, 0.1, 0.55, 0.3, GLASS),
            cylinder(0, 0.15, 0.1, 0.3, 0.3, BROWN)]


def stove_burner(s) -> list[Part]:
    return [cylinder(0, 0, 0, 1, 0.5, BLACK), ring(0, 1, 0, 0.3, 0.08, DARK, axis=(0, 1, 0))]


def stove_knob(s) -> list[Part]:
    return [rod((0, 0.5, -0.5), (0, 0.5, 0.5), 0.5, BLACK, sections=16), box(-0.08, 0.1, 0.3, 0.08, 0.9, 0.55, METAL)]


def kettle(s) -> list[Part]:
    return [lathe([(0, 0), (0.34, 0), (0.36, 0.4), (0.26, 0.72), (0.1, 0.78), (0, 0.78)], METAL),
            rod((0.2, 0.3, 0), (0.5, 0.7, 0), 0.05, METAL), ring(0, 0.8, 0, 0.22, 0.04, BLACK, axis=(1, 0, 0))]


def vacuum(s) -> list[Part]:
    return [box(-0.5, 0, -0.2, 0.5, 0.08, 0.5, DARK), box(-0.25, 0.05, -0.5, 0.25, 0.45, 0.0, RED),
            rod((0, 0.4, -0.3), (0, 1, -0.4), 0.05, GREY)]


def television(s) -> list[Part]:
    return [box(-0.5, 0.12, -0.1, 0.5, 1, 0.1, BLACK), box(-0.47, 0.15, 0.1, 0.47, 0.97, 0.12, SCREEN),
            box(-0.05, 0.03, -0.05, 0.05, 0.14, 0.05, DARK), box(-0.25, 0, -0.5, 0.25, 0.03, 0.5, DARK)]


def laptop(s) -> list[Part]:
    return [box(-0.5, 0, -0.45, 0.5, 0.06, 0.5, GREY), box(-0.45, 0.06, 0.05, 0.45, 0.07, 0.42, DARK),
            box(-0.5, 0.06, -0.5, 0.5, 1, -0.42, GREY), box(-0.46, 0.1, -0.42, 0.46, 0.96, -0.41, SCREEN)]


def desktop(s) -> list[Part]:
    return [box(-0.5, 0.2, -0.1, 0.5, 1, 0.05, BLACK), box(-0.47, 0.23, 0.05, 0.47, 0.97, 0.07, SCREEN),
            box(-0.05, 0.02, -0.05, 0.05, 0.22, 0.05, DARK), box(-0.25, 0, -0.5, 0.25, 0.02, 0.3, DARK)]


def phone(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.8, 0.5, BLACK), box(-0.45, 0.8, -0.44, 0.45, 1, 0.44, SCREEN)]


def remote(s) -> list[Part]:
    parts = [box(-0.5, 0, -0.5, 0.5, 0.8, 0.5, DARK)]
    parts += [box(-0.25 + 0.3 * i, 0.8, 0.1 + 0.15 * j, -0.1 + 0.3 * i, 1, 0.2 + 0.15 * j, GREY)
              for i in range(2) for j in range(2)]
    parts.append(ball(0, 0.85, -0.25, 0.15, RED, ry=0.15))
    return parts


def compact_disc(s) -> list[Part]:
    return [lathe([(0.08, 0), (0.5, 0), (0.5, 1), (0.08, 1)], SILVER, sections=32)]


def alarm_clock(s) -> list[Part]:
    return [box(-0.5, 0.06, -0.5, 0.5, 1, 0.3, DARK), box(-0.4, 0.16, 0.3, 0.4, 0.9, 0.36, WHITE),
            box(-0.02, 0.52, 0.36, 0.02, 0.82, 0.42, BLACK),
            box(-0.02, 0.5, 0.36, 0.25, 0.54, 0.42, BLACK), *_legs(0.06, 0.1, DARK, inset=0.05)]


def watch(s) -> list[Part]:
    return [box(-0.2, 0, -0.5, 0.2, 0.25, 0.5, BLACK), cylinder(0, 0, 0.25, 1, 0.42, SILVER),
            cylinder(0, 0, 0.95, 1.0, 0.34, WHITE)]


# --- fixtures ----------------------------------------------------------------------------------------------
def light_switch(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.1, WHITE), box(-0.12, 0.35, 0.1, 0.12, 0.65, 0.5, OFF_WHITE)]


def window(s) -> list[Part]:
    frame = WHITE
    return [box(-0.5, 0, -0.5, 0.5, 0.05, 0.5, frame), box(-0.5, 0.95, -0.5, 0.5, 1, 0.5, frame),
            box(-0.5, 0, -0.5, -0.46, 1, 0.5, frame), box(0.46, 0, -0.5, 0.5, 1, 0.5, frame),
            box(-0.02, 0.05, -0.3, 0.02, 0.95, 0.3, frame), box(-0.46, 0.48, -0.3, 0.46, 0.52, 0.3, frame),
            box(-0.46, 0.05, -0.05, 0.46, 0.95, 0.05, GLASS)]


def blinds(s) -> list[Part]:
    parts = [box(-0.5, 0.94, -0.5, 0.5, 1, 0.5, WHITE)]
    parts += [box(-0.49, y, -0.3, 0.49, y + 0.02, 0.3, OFF_WHITE) for y in np.arange(0.02, 0.92, 0.06)]
    return parts


def curtains(s) -> list[Part]:
    parts = [rod((-0.5, 0.98, 0), (0.5, 0.98, 0), 0.02, METAL)]
    folds = np.linspace(-0.5, 0.5, 13)
    for i, (a, b) in enumerate(zip(folds, folds[1:], strict=False)):
        z = -0.4 if i % 2 else 0.3
        parts.append(box(a, 0, z, b, 0.97, z + 0.1, BEIGE))
    return parts


def faucet(s) -> list[Part]:
    return [cylinder(0, -0.3, 0, 0.1, 0.2, METAL), cylinder(0, -0.3, 0.1, 0.8, 0.1, METAL),
            rod((0, 0.8, -0.3), (0, 0.85, 0.5), 0.08, METAL), box(-0.45, 0.3, -0.35, 0.45, 0.38, -0.25, METAL)]


def toilet(s) -> list[Part]:
    return [lathe([(0, 0), (0.22, 0), (0.3, 0.25), (0.42, 0.42), (0, 0.42)], CERAMIC, z=0.12),
            cylinder(0, 0.12, 0.42, 0.46, 0.44, WHITE, rz=0.38), box(-0.45, 0.4, -0.5, 0.45, 1, -0.22, CERAMIC)]


def sink(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.85, 0.45, WOOD), box(-0.5, 0.85, -0.5, 0.5, 0.92, 0.5, OFF_WHITE),
            cylinder(0, 0.05, 0.9, 0.93, 0.32, METAL, rz=0.3), box(-0.45, 0.05, 0.45, 0.45, 0.8, 0.48, LIGHT_WOOD),
            cylinder(0, -0.4, 0.92, 1, 0.03, METAL)]


def basin(s) -> list[Part]:
    return [lathe([(0, 0), (0.42, 0.05), (0.5, 1), (0.46, 1), (0.38, 0.25), (0, 0.2)], CERAMIC)]


def bathtub(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.98, 0.5, CERAMIC), box(-0.44, 0.3, -0.42, 0.44, 1, 0.42, (0.85, 0.9, 0.93))]


def shower_head(s) -> list[Part]:
    return [rod((0, 0.8, -0.5), (0, 0.8, 0.1), 0.08, METAL), lathe([(0, 0), (0.5, 0.3), (0.5, 0.5), (0, 0.6)],
                                                                    METAL, z=0.2)]


def glass_panel(s) -> list[Part]:
    return [box(-0.5, 0, -0.04, 0.5, 1, 0.04, GLASS), box(-0.5, 0, -0.06, -0.47, 1, 0.06, METAL),
            box(0.47, 0, -0.06, 0.5, 1, 0.06, METAL), box(-0.5, 0.97, -0.06, 0.5, 1, 0.06, METAL)]


def shower_curtain(s) -> list[Part]:
    return [rod((-0.5, 0.99, 0), (0.5, 0.99, 0), 0.02, METAL),
            *[box(a, 0.05, -0.2 if i % 2 else 0.1, a + 0.1, 0.97, 0.1 if i % 2 else 0.4, (0.85, 0.92, 0.95))
              for i, a in enumerate(np.arange(-0.5, 0.5, 0.1))]]


def towel_holder(s) -> list[Part]:
    return [box(-0.5, 0.3, -0.5, -0.42, 1, -0.3, METAL), box(0.42, 0.3, -0.5, 0.5, 1, -0.3, METAL),
            rod((-0.46, 0.6, 0.2), (0.46, 0.6, 0.2), 0.06, METAL), rod((-0.46, 0.6, -0.4), (-0.46, 0.6, 0.2), 0.05,
                                                                     METAL),
            rod((0.46, 0.6, -0.4), (0.46, 0.6, 0.2), 0.05, METAL), box(-0.4, 0, 0.05, 0.4, 0.58, 0.3, WHITE)]


def hand_towel_holder(s) -> list[Part]:
    return [box(-0.15, 0.7, -0.5, 0.15, 1, -0.4, METAL), ring(0, 0.45, 0, 0.4, 0.05, METAL, axis=(0, 0, 1))]


def toilet_paper_hanger(s) -> list[Part]:
    return [box(-0.5, 0.35, -0.5, 0.5, 0.65, -0.4, METAL), rod((-0.45, 0.5, -0.4), (-0.45, 0.5, 0.3), 0.05, METAL),
            rod((-0.45, 0.5, 0.0), (0.45, 0.5, 0.0), 0.45, WHITE)]


# --- lighting and decoration -------------------------------------------------------------------------------
def desk_lamp(s) -> list[Part]:
    return [cylinder(0, 0, 0, 0.05, 0.45, DARK), rod((0, 0.05, 0), (0, 0.6, 0), 0.04, METAL),
            lathe([(0, 0.55), (0.5, 0.55), (0.25, 1), (0, 1)], BEIGE)]


def floor_lamp(s) -> list[Part]:
    return [cylinder(0, 0, 0, 0.03, 0.45, DARK), rod((0, 0.03, 0), (0, 0.78, 0), 0.04, METAL),
            lathe([(0, 0.75), (0.5, 0.75), (0.32, 1), (0, 1)], OFF_WHITE)]


def candle(s) -> list[Part]:
    return [cylinder(0, 0, 0, 0.75, 0.5, OFF_WHITE), rod((0, 0.75, 0), (0, 0.82, 0), 0.04, BLACK),
            ball(0, 0.9, 0, 0.12, YELLOW, ry=0.1)]


def painting(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.2, DARK_WOOD), box(-0.44, 0.07, 0.2, 0.44, 0.93, 0.3, (0.55, 0.7, 0.85)),
            box(-0.44, 0.07, 0.3, 0.44, 0.4, 0.35, GREEN), ball(0.2, 0.7, 0.32, 0.1, YELLOW, rz=0.02),
            box(-0.3, 0.35, 0.3, -0.05, 0.6, 0.36, TERRACOTTA)]


def poster(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.3, PAPER), box(-0.4, 0.45, 0.3, 0.4, 0.9, 0.5, BLUE),
            box(-0.4, 0.1, 0.3, 0.4, 0.18, 0.5, BLACK), box(-0.4, 0.25, 0.3, 0.1, 0.32, 0.5, RED)]


def mirror(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.2, DARK_WOOD), box(-0.44, 0.05, 0.2, 0.44, 0.95, 0.3, SILVER)]


def vase(rgb=(0.35, 0.55, 0.7)) -> Builder:
    return lambda s: [lathe([(0, 0), (0.3, 0), (0.5, 0.35), (0.28, 0.8), (0.32, 1), (0.26, 1), (0, 0.9)], rgb)]


def statue(s) -> list[Part]:
    return [box(-0.45, 0, -0.45, 0.45, 0.15, 0.45, DARK), cylinder(0, 0, 0.15, 0.6, 0.22, (0.75, 0.7, 0.62)),
            ball(0, 0.68, 0, 0.28, (0.75, 0.7, 0.62)), ball(0, 0.9, 0, 0.14, (0.75, 0.7, 0.62))]


def house_plant(s) -> list[Part]:
    return [lathe([(0, 0), (0.28, 0), (0.36, 0.35), (0, 0.35)], TERRACOTTA),
            ball(0, 0.62, 0, 0.42, LEAF, ry=0.3), ball(0.2, 0.78, 0.1, 0.3, GREEN, ry=0.22),
            ball(-0.2, 0.75, -0.1, 0.28, LEAF, ry=0.24)]


def table_top_decor(s) -> list[Part]:
    return [cylinder(0, 0, 0, 0.15, 0.4, DARK_WOOD), ball(0, 0.55, 0, 0.45, (0.6, 0.3, 0.5), ry=0.42)]


def teddy_bear(s) -> list[Part]:
    fur = (0.6, 0.42, 0.25)
    return [ball(0, 0.35, 0, 0.36, fur, ry=0.35), ball(0, 0.78, 0.05, 0.26, fur, ry=0.22),
            ball(-0.2, 0.97, 0.03, 0.09, fur), ball(0.2, 0.97, 0.03, 0.09, fur),
            ball(-0.32, 0.1, 0.25, 0.14, fur, ry=0.1), ball(0.32, 0.1, 0.25, 0.14, fur, ry=0.1),
            ball(0, 0.74, 0.28, 0.08, BEIGE)]


# --- kitchenware and food ----------------------------------------------------------------------------------
def bowl(rgb=CERAMIC) -> Builder:
    return lambda s: [lathe([(0, 0), (0.3, 0), (0.5, 1), (0.45, 1), (0.25, 0.15), (0, 0.15)], rgb)]


def plate(s) -> list[Part]:
    return [lathe([(0, 0), (0.35, 0), (0.5, 1), (0.46, 1), (0.32, 0.4), (0, 0.4)], CERAMIC, sections=32)]


def cup(rgb=GLASS) -> Builder:
    return lambda s: [lathe([(0, 0), (0.38, 0), (0.5, 1), (0.44, 1), (0.33, 0.08), (0, 0.08)], rgb)]


def mug(s) -> list[Part]:
    return [lathe([(0, 0), (0.36, 0), (0.36, 1), (0.31, 1), (0.31, 0.08), (0, 0.08)], (0.85, 0.3, 0.25), x=-0.14),
            ring(0.28, 0.5, 0, 0.2, 0.05, (0.85, 0.3, 0.25), axis=(0, 0, 1))]


def pot(s) -> list[Part]:
    return [lathe([(0, 0), (0.38, 0), (0.4, 1), (0.36, 1), (0.34, 0.05), (0, 0.05)], METAL),
            box(-0.5, 0.8, -0.06, -0.4, 0.88, 0.06, BLACK), box(0.4, 0.8, -0.06, 0.5, 0.88, 0.06, BLACK)]


def pan(s) -> list[Part]:
    return [lathe([(0, 0), (0.26, 0), (0.3, 1), (0.27, 1), (0.24, 0.15), (0, 0.15)], DARK, z=-0.2),
            box(-0.04, 0.5, 0.1, 0.04, 0.7, 0.5, BLACK)]


def _long(parts_along_z: Callable[[], list[Part]]) -> Builder:
    """A long object lying down: built along Z, turned to run along X when its box is longer in X."""
    def build(s):
        parts = parts_along_z()
        return turn(parts, 90) if s[0] > s[2] else parts
    return build


def utensil(head: str, rgb=METAL, handle=METAL) -> Builder:
    def parts() -> list[Part]:
        out = [box(-0.12, 0, 0.0, 0.12, 0.4, 0.5, handle)]
        if head == "fork":
            out += [box(-0.4, 0, -0.2, 0.4, 0.3, 0.0, rgb)]
            out += [box(x - 0.05, 0, -0.5, x + 0.05, 0.3, -0.2, rgb) for x in (-0.33, -0.11, 0.11, 0.33)]
        elif head == "knife":
            out += [box(-0.3, 0, -0.5, 0.3, 0.25, 0.0, rgb)]
        elif head == "spatula":
            out += [box(-0.5, 0, -0.5, 0.5, 0.2, -0.1, rgb)]
        else:  # spoon, ladle
            out += [ball(0, 0.5, -0.3, 0.5, rgb, ry=0.5, rz=0.2)]
        return out
    return _long(parts)


def bottle(rgb=(0.3, 0.6, 0.4), neck: float = 0.65) -> Builder:
    return lambda s: [lathe([(0, 0), (0.5, 0), (0.5, neck), (0.2, neck + 0.12), (0.18, 1), (0, 1)], rgb)]


def soap_bottle(s) -> list[Part]:
    return [lathe([(0, 0), (0.5, 0), (0.5, 0.7), (0.2, 0.78), (0, 0.78)], (0.5, 0.75, 0.85)),
            cylinder(0, 0, 0.78, 0.95, 0.1, WHITE), box(-0.05, 0.9, 0, 0.05, 0.97, 0.4, WHITE)]


def spray_bottle(s) -> list[Part]:
    return [lathe([(0, 0), (0.4, 0), (0.4, 0.65), (0.15, 0.72), (0, 0.72)], (0.35, 0.6, 0.9), z=-0.1),
            box(-0.12, 0.72, -0.25, 0.12, 1, 0.2, WHITE), box(-0.06, 0.8, 0.2, 0.06, 0.95, 0.5, WHITE)]


def shaker(top) -> Builder:
    return lambda s: [lathe([(0, 0), (0.45, 0), (0.5, 0.75), (0, 0.75)], GLASS),
                      lathe([(0, 0.75), (0.5, 0.75), (0.4, 1), (0, 1)], top)]


def sponge(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.7, 0.5, YELLOW), box(-0.5, 0.7, -0.5, 0.5, 1, 0.5, GREEN)]


def foil(s) -> list[Part]:
    return _long(lambda: [box(-0.5, 0, -0.5, 0.5, 1, 0.5, (0.9, 0.9, 0.85)),
                          box(-0.5, 0.7, -0.5, 0.5, 1, 0.5, BLUE)])(s)


def paper_towel(s) -> list[Part]:
    return [cylinder(0, 0, 0, 0.06, 0.5, WOOD), cylinder(0, 0, 0.06, 1, 0.45, WHITE),
            rod((0, 0, 0), (0, 1, 0), 0.05, WOOD)]


def fruit(rgb, stem=True) -> Builder:
    def build(s):
        parts = [ball(0, 0.45, 0, 0.5, rgb, ry=0.45)]
        if stem:
            parts += [rod((0, 0.85, 0), (0.05, 1, 0), 0.04, BROWN), ball(0.12, 0.92, 0, 0.1, LEAF, ry=0.03)]
        return parts
    return build


def bread(s) -> list[Part]:
    return _long(lambda: [box(-0.5, 0, -0.5, 0.5, 0.55, 0.5, (0.8, 0.55, 0.25)),
                          ball(0, 0.55, 0, 0.5, (0.7, 0.45, 0.2), ry=0.45, rz=0.5)])(s)


def lettuce(s) -> list[Part]:
    return [ball(0, 0.45, 0, 0.45, (0.55, 0.8, 0.35)), ball(0.15, 0.5, 0.1, 0.35, (0.45, 0.75, 0.3)),
            ball(-0.15, 0.55, -0.1, 0.33, (0.6, 0.85, 0.4))]


# --- textiles, toiletries, small things -------------------------------------------------------------------
def folded(rgb) -> Builder:
    return lambda s: [box(-0.5, 0, -0.5, 0.5, 0.5, 0.5, rgb), box(-0.48, 0.5, -0.5, 0.48, 1, 0.45, rgb),
                      box(-0.5, 0.45, 0.45, 0.5, 0.55, 0.5, OFF_WHITE)]


def pillow(s) -> list[Part]:
    return [ball(0, 0.5, 0, 0.5, (0.9, 0.88, 0.8), ry=0.5, rz=0.5, subdivisions=3)]


def soap_bar(s) -> list[Part]:
    return [box(-0.45, 0, -0.45, 0.45, 1, 0.45, (0.95, 0.85, 0.9)), ball(0, 0.5, 0, 0.5, (0.95, 0.85, 0.9), ry=0.5)]


def toilet_paper(s) -> list[Part]:
    return [lathe([(0.15, 0), (0.5, 0), (0.5, 1), (0.15, 1)], WHITE)]


def tissue_box(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.8, 0.5, (0.45, 0.65, 0.8)), ball(0, 0.85, 0, 0.2, WHITE, ry=0.15)]


def scrub_brush(s) -> list[Part]:
    return [rod((0, 0.15, 0), (0, 1, 0), 0.12, WHITE), ball(0, 0.12, 0, 0.5, GREY, ry=0.12)]


def plunger(s) -> list[Part]:
    return [lathe([(0, 0), (0.5, 0), (0.2, 0.25), (0, 0.25)], RED), rod((0, 0.2, 0), (0, 1, 0), 0.1, WOOD)]


def book(cover=(0.55, 0.15, 0.15)) -> Builder:
    return lambda s: [box(-0.5, 0, -0.5, 0.5, 0.12, 0.5, cover), box(-0.5, 0.88, -0.5, 0.5, 1, 0.5, cover),
                      box(-0.5, 0, -0.5, -0.42, 1, 0.5, cover), box(-0.42, 0.12, -0.47, 0.48, 0.88, 0.47, PAPER)]


def pen(body=BLUE) -> Builder:
    return _long(lambda: [rod((0, 0.5, -0.5), (0, 0.5, 0.35), 0.5, body), rod((0, 0.5, 0.35), (0, 0.5, 0.5), 0.25,
                                                                            BLACK)])


def newspaper(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.5, (0.85, 0.85, 0.82)),
            *[box(-0.4, 1, z, 0.4, 1.02, z + 0.03, GREY) for z in np.arange(-0.4, 0.4, 0.1)]]


def credit_card(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.5, (0.2, 0.35, 0.7)), box(-0.45, 1, 0.1, 0.45, 1.05, 0.25, YELLOW)]


def key_chain(s) -> list[Part]:
    return [ring(-0.25, 0.5, 0, 0.22, 0.06, METAL, axis=(0, 1, 0)), box(0, 0, -0.1, 0.5, 1, 0.1, METAL)]


def boots(s) -> list[Part]:
    out = []
    for x in (-0.27, 0.27):
        out += [box(x - 0.2, 0, -0.5, x + 0.2, 1, -0.05, BROWN), box(x - 0.2, 0, -0.05, x + 0.2, 0.3, 0.5, BROWN)]
    return out


def bat(s) -> list[Part]:
    parts = [lathe([(0, 0), (0.5, 0), (0.5, 0.4), (0.25, 0.9), (0.3, 1), (0, 1)], LIGHT_WOOD)]
    return parts if s[1] >= max(s[0], s[2]) else _lying_along_z(parts, s)


def _lying_along_z(parts: list[Part], s) -> list[Part]:
    """Lay an upright lathe down along Z (or X when the box is longer in X)."""
    from ..scenes import frames

    out = []
    tilt = frames.linear(frames.rotation_between([0, 1, 0], [0, 0, 1]))
    for mesh, rgb in parts:
        mesh = mesh.copy()
        mesh.apply_transform(tilt)
        out.append((mesh, rgb))
    return turn(out, 90) if s[0] > s[2] else out


def basketball(s) -> list[Part]:
    return [ball(0, 0.5, 0, 0.5, ORANGE, subdivisions=3), ring(0, 0.5, 0, 0.5, 0.02, BLACK, axis=(1, 0, 0)),
            ring(0, 0.5, 0, 0.5, 0.02, BLACK, axis=(0, 0, 1))]


def tennis_racket(s) -> list[Part]:
    parts = [ring(0, 0.7, 0, 0.28, 0.03, BLUE, axis=(0, 0, 1)), rod((0, 0, 0), (0, 0.42, 0), 0.05, BLACK),
             box(-0.25, 0.45, -0.01, 0.25, 0.95, 0.01, (0.9, 0.9, 0.8))]
    return parts if s[1] >= max(s[0], s[2]) else _lying_along_z(parts, s)


def dumbbell(s) -> list[Part]:
    return _long(lambda: [rod((0, 0.5, -0.5), (0, 0.5, 0.5), 0.12, METAL),
                          rod((0, 0.5, -0.45), (0, 0.5, -0.2), 0.5, DARK), rod((0, 0.5, 0.2), (0, 0.5, 0.45), 0.5,
                                                                                 DARK)])(s)


def cardboard_box(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 0.95, 0.5, (0.72, 0.55, 0.35)), box(-0.5, 0.95, -0.5, 0.5, 1, -0.02,
                                                                         (0.65, 0.48, 0.3)),
            box(-0.1, 0.3, 0.5, 0.1, 0.5, 0.51, PAPER)]


def garbage_can(s) -> list[Part]:
    return [lathe([(0, 0), (0.4, 0), (0.5, 0.95), (0.47, 0.95), (0.38, 0.05), (0, 0.05)], GREY),
            ring(0, 0.96, 0, 0.48, 0.03, DARK, axis=(0, 1, 0))]


def garbage_bag(s) -> list[Part]:
    return [ball(0, 0.42, 0, 0.5, BLACK, ry=0.42), ball(0, 0.9, 0, 0.12, BLACK, ry=0.1)]


def hamper(s) -> list[Part]:
    return [lathe([(0, 0), (0.42, 0), (0.5, 1), (0.46, 1), (0.38, 0.04), (0, 0.04)], (0.8, 0.7, 0.5)),
            ring(0, 0.6, 0, 0.45, 0.02, BROWN, axis=(0, 1, 0))]


def watering_can(s) -> list[Part]:
    return [cylinder(-0.1, 0, 0, 0.65, 0.35, GREEN), rod((0.2, 0.2, 0), (0.5, 0.9, 0), 0.06, GREEN),
            ring(-0.1, 0.75, 0, 0.25, 0.04, GREEN, axis=(0, 0, 1))]


def room(s) -> list[Part]:
    """Floor and four walls of a room box (unit size; instances scale it)."""
    wall = (0.9, 0.88, 0.84)
    return [box(-0.5, 0, -0.5, 0.5, 0.01, 0.5, LIGHT_WOOD), box(-0.5, 0, -0.5, 0.5, 1, -0.49, wall),
            box(-0.5, 0, -0.5, -0.49, 1, 0.5, wall), box(0.49, 0, -0.5, 0.5, 1, 0.5, wall),
            box(-0.5, 0, 0.49, 0.5, 1, 0.5, wall)]


def plain_box(s) -> list[Part]:
    return [box(-0.5, 0, -0.5, 0.5, 1, 0.5, GREY)]


BUILDERS: dict[str, Builder] = {
    # furniture
    "DiningTable": table(), "CoffeeTable": coffee_table, "SideTable": side_table, "Desk": desk,
    "TVStand": tv_stand, "CounterTop": counter_top, "Chair": chair(), "ArmChair": armchair(),
    "Sofa": armchair(BLUE, seats=3), "Stool": stool, "Ottoman": ottoman, "Footstool": ottoman, "Bed": bed,
    "DogBed": dog_bed, "Cabinet": cabinet(), "Drawer": drawer, "Dresser": dresser, "Shelf": shelf,
    "ShelvingUnit": shelving_unit, "Safe": safe,
    # appliances, electronics
    "Fridge": fridge, "Microwave": microwave, "Toaster": toaster, "CoffeeMachine": coffee_machine,
    "StoveBurner": stove_burner, "StoveKnob": stove_knob, "Kettle": kettle, "VacuumCleaner": vacuum,
    "Television": television, "Laptop": laptop,
    "Desktop": desktop, "CellPhone": _long(lambda: phone(None)), "RemoteControl": _long(lambda: remote(None)),
    "CD": compact_disc, "AlarmClock": alarm_clock, "Watch": watch,
    # fixtures
    "LightSwitch": light_switch, "Window": window, "Blinds": blinds, "Curtains": curtains, "Faucet": faucet,
    "Toilet": toilet, "Sink": sink, "SinkBasin": basin, "Bathtub": bathtub, "BathtubBasin": basin,
    "ShowerHead": shower_head, "ShowerDoor": glass_panel, "ShowerGlass": glass_panel,
    "ShowerCurtain": shower_curtain, "TowelHolder": towel_holder, "HandTowelHolder": hand_towel_holder,
    "ToiletPaperHanger": toilet_paper_hanger,
    # lighting, decoration
    "DeskLamp": desk_lamp, "FloorLamp": floor_lamp, "Candle": candle, "Painting": painting, "Poster": poster,
    "Mirror": mirror, "Vase": vase(), "Statue": statue, "HousePlant": house_plant,
    "RoomDecor": vase((0.8, 0.6, 0.3)), "TableTopDecor": table_top_decor, "TeddyBear": teddy_bear,
    # kitchenware, food
    "Bowl": bowl(), "Plate": plate, "Cup": cup(), "Mug": mug, "Pot": pot, "Pan": pan,
    "Fork": utensil("fork"), "Knife": utensil("knife", handle=BLACK), "ButterKnife": utensil("knife"),
    "Spoon": utensil("spoon"), "Spatula": utensil("spatula", rgb=BLACK, handle=BLACK), "Ladle": utensil("ladle"),
    "Bottle": bottle(), "WineBottle": bottle((0.15, 0.3, 0.15), neck=0.55), "SoapBottle": soap_bottle,
    "SprayBottle": spray_bottle, "SaltShaker": shaker(METAL), "PepperShaker": shaker(BLACK), "DishSponge": sponge,
    "AluminumFoil": foil, "PaperTowelRoll": paper_towel,
    "Apple": fruit(RED), "Bread": bread, "Egg": fruit((0.95, 0.9, 0.8), stem=False), "Lettuce": lettuce,
    "Potato": fruit((0.65, 0.5, 0.3), stem=False), "Tomato": fruit((0.9, 0.2, 0.1)),
    # textiles, toiletries, stationery, personal, sports, containers
    "Towel": folded(WHITE), "HandTowel": folded((0.6, 0.75, 0.85)), "Cloth": folded((0.85, 0.6, 0.6)),
    "Pillow": pillow, "SoapBar": soap_bar, "ToiletPaper": toilet_paper, "TissueBox": tissue_box,
    "ScrubBrush": scrub_brush, "Plunger": plunger, "Book": book(), "Pen": pen(), "Pencil": pen(YELLOW),
    "Newspaper": newspaper, "CreditCard": credit_card, "KeyChain": key_chain, "Boots": boots,
    "BaseballBat": bat, "BasketBall": basketball, "TennisRacket": tennis_racket, "Dumbbell": dumbbell,
    "Box": cardboard_box, "GarbageCan": garbage_can, "GarbageBag": garbage_bag, "LaundryHamper": hamper,
    "WateringCan": watering_can, "Room": room,
}


def procedural_model(object_type: str, size) -> trimesh.Scene:
    """The low-poly model of ``object_type`` fitted exactly to ``size`` (metres, canonical frame)."""
    size = np.maximum(np.asarray(size, dtype=float), 1e-3)
    return assemble(BUILDERS.get(object_type, plain_box)(size), size)
