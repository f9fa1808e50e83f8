"""The pieces of MJCF the tests' inline models share, each returned as XML text.

A test's model stays written where the test is, in MJCF; these write the parts models repeat
(the document around the world body, a body on a free joint holding one geom, an arm of capsules
on hinges, a link of a chain, an actuator on each joint), with the attributes as MJCF spells them.
"""

from __future__ import annotations

from typing import NamedTuple


def mjcf(*worldbody: str, option: str = "", actuator: str = "") -> str:
    """A model: ``<option {option}/>`` (when given), a world body holding ``worldbody`` and
    ``actuator`` (``motors(...)``) after it."""
    head = f"  <option {option}/>\n" if option else ""
    body = "".join(f"    {element}\n" for element in worldbody)
    tail = f"  {actuator}\n" if actuator else ""
    return f"<mujoco>\n{head}  <worldbody>\n{body}  </worldbody>\n{tail}</mujoco>\n"


def free(name: str, pos: str, geom: str) -> str:
    """A body ``name`` at ``pos`` on a free joint, holding one geom of the attributes ``geom``
    (``'name="ball" size=".05"'``)."""
    return f'<body name="{name}" pos="{pos}"><freejoint/><geom {geom}/></body>'


class Capsule(NamedTuple):
    """A link of ``arm``: the body and its capsule ``name`` on the hinge ``joint``; the capsule
    runs ``length`` along the body's x axis, of ``radius``."""

    name: str
    joint: str
    length: str
    radius: str


def arm(pos: str, *links: Capsule, **hinge: str | tuple[str, ...]) -> str:
    """A chain of capsules on hinges: the first link at ``pos``, each next one at the tip of the
    one before; ``hinge`` are the hinges' other attributes (a tuple: a value for each link)."""
    xml = ""
    for i in reversed(range(len(links))):
        name, joint, length, radius = links[i]
        at = pos if i == 0 else f"{links[i - 1].length} 0 0"
        xml = (
            f'<body name="{name}" pos="{at}"><joint name="{joint}" type="hinge"{_spell(hinge, i)}/>'
            f'<geom name="{name}" type="capsule" fromto="0 0 0 {length} 0 0" size="{radius}"/>'
            f"{xml}</body>"
        )
    return xml


def link(name: str, joint: str, pos: str, fromto: str, *children: str, **hinge: str) -> str:
    """A body ``name`` at ``pos`` on the hinge ``joint`` (its other attributes ``hinge``), holding
    a capsule ``name`` of ``fromto`` and radius .03, and the bodies ``children`` (``link(...)``)."""
    return (
        f'<body name="{name}" pos="{pos}"><joint name="{joint}" type="hinge"{_spell(hinge, 0)}/>'
        f'<geom name="{name}" type="capsule" fromto="{fromto}" size=".03"/>{"".join(children)}'
        "</body>"
    )


def motors(*joints: str, kind: str = "motor", **attributes: str | tuple[str, ...]) -> str:
    """An ``<actuator>`` of an actuator ``kind`` (``<motor>``, ``<position>``, ...) on each joint,
    with the attributes given (a tuple gives each joint its own value: ``gear=("2", "1")``)."""
    each = (f'<{kind} joint="{j}"{_spell(attributes, i)}/>' for i, j in enumerate(joints))
    return f"<actuator>{''.join(each)}</actuator>"


def _spell(attributes: dict[str, str | tuple[str, ...]], i: int) -> str:
    """The attributes of the ``i``-th element: a tuple's ``i``-th value, a string as it is."""
    return "".join(f' {k}="{v[i] if isinstance(v, tuple) else v}"' for k, v in attributes.items())
