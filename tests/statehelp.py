"""Object states and scene-changing events as the tests write them (vocabulary 2: each change carries the
states it left), for the replay's tests and the server's that store trials to replay."""

import numpy as np


def obj(id_, x=0.0, z=0.0, parent="room", model="m-chair", category="Chair", turn_deg=0.0):
    """An object state as a scene file lists it, at (x, 0, z) turned by ``turn_deg`` about +Y."""
    a = np.radians(turn_deg)
    m = np.eye(4)
    m[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    m[:3, 3] = [x, 0.0, z]
    return {"id": id_, "model_id": model, "category": category, "size": [0.5, 0.9, 0.5],
            "transform": m.T.reshape(-1).tolist(), "parent": parent, "surface_type": "up_interior",
            "attachment_face": "bottom", "contact_point": [x, 0.0, z], "contact_normal": [0.0, 1.0, 0.0]}


ROOM = {**obj("room", parent=None, model="room", category="Room"), "surface_type": None, "attachment_face": None,
        "contact_point": None, "contact_normal": None}


def event(seq, kind, t=None, **payload):
    return {"seq": seq, "t": 1.7e12 + 1000.0 * seq if t is None else t, "type": kind, "trial": 0, "payload": payload}


def insert(seq, state, **extra):
    return event(seq, "insert", object=state["id"], model=state["model_id"], category=state["category"], rank=1,
                 source="fixed", objects=[state], **extra)


# --- the pure replay ----------------------------------------------------------------------------------------------
