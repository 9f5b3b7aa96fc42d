"""Writes the example programs (Blockly workspaces in rosgate-program files) and index.json.

    python3 examples/make_examples.py

The programs are built here from small helpers so they stay readable and consistent;
the JSON files are what the IDE's Examples menu loads.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


class Program:
    def __init__(self, name: str, robot: str, title: str, about: str):
        self.name, self.robot, self.title, self.about = name, robot, title, about
        self.variables: dict[str, str] = {}
        self.tops: list[dict] = []

    def var(self, name: str) -> dict:
        vid = self.variables.setdefault(name, f"var-{name}")
        return {"id": vid}

    def top(self, first: dict, x: int = 20, y: int = 20) -> None:
        self.tops.append({**first, "x": x, "y": y})

    def save(self, file: str) -> dict:
        doc = {
            "format": "rosgate-program",
            "version": 1,
            "name": self.title,
            "robot": self.robot,
            "about": self.about,
            "blocks": [],
            "workspace": {
                "blocks": {"languageVersion": 0, "blocks": self.tops},
                "variables": [{"name": n, "id": i} for n, i in self.variables.items()],
            },
        }
        (HERE / file).write_text(json.dumps(doc, indent=1) + "\n")
        return {"file": file, "title": self.title, "robot": self.robot, "about": self.about}


def block(type_: str, fields: dict | None = None, inputs: dict | None = None, **extra) -> dict:
    b = {"type": type_}
    if fields:
        b["fields"] = fields
    if inputs:
        b["inputs"] = {k: (v if "block" in v or "shadow" in v else {"block": v}) for k, v in inputs.items()}
    b.update({k: v for k, v in extra.items() if v is not None})
    return b


def seq(*blocks: dict) -> dict:
    """Chains statement blocks with `next`."""
    for a, b in zip(blocks, blocks[1:]):
        a["next"] = {"block": b}
    return blocks[0]


def num(n: float) -> dict:
    return {"shadow": {"type": "math_number", "fields": {"NUM": n}}}


def text(s: str) -> dict:
    return {"shadow": {"type": "text", "fields": {"TEXT": s}}}


def number(n: float) -> dict:
    return block("math_number", {"NUM": n})


def arith(op: str, a, b) -> dict:
    return block("math_arithmetic", {"OP": op}, {"A": a, "B": b})


def get(p: Program, name: str) -> dict:
    return block("variables_get", {"VAR": p.var(name)})


def set_(p: Program, name: str, value) -> dict:
    return block("variables_set", {"VAR": p.var(name)}, {"VALUE": value})


def log(value) -> dict:
    return block("ros_log", inputs={"VALUE": value})


def compare(op: str, a, b) -> dict:
    return block("logic_compare", {"OP": op}, {"A": a, "B": b})


def if_(cond, then: dict, *elifs, else_: dict | None = None) -> dict:
    inputs = {"IF0": cond, "DO0": then}
    for i, (c, d) in enumerate(elifs, start=1):
        inputs[f"IF{i}"] = c
        inputs[f"DO{i}"] = d
    if else_ is not None:
        inputs["ELSE"] = else_
    return block("controls_if", inputs=inputs,
                 extraState={"elseIfCount": len(elifs), "hasElse": else_ is not None} if elifs or else_ else None)


# ---- turtlesim ---------------------------------------------------------------
def turtle(name="turtle1"):
    return text(name)


def move(dist, who=None):
    return block("turtle_move", inputs={"TURTLE": who or turtle(), "DIST": dist})


def turn(deg, left=True, who=None):
    return block("turtle_turn", {"DIR": "1" if left else "-1"}, {"TURTLE": who or turtle(), "ANGLE": deg})


def pen(colour: str, width: float = 3, who=None):
    return block("turtle_pen", {"OFF": "0", "COLOUR": colour}, {"TURTLE": who or turtle(), "WIDTH": num(width)})


def drive_square() -> dict:
    p = Program("drive_square", "turtlesim", "drive a square",
                "turtle1 draws a square of side 3 and ends where it started.")
    p.top(seq(
        pen("255 220 0", 4),
        block("controls_repeat_ext", inputs={"TIMES": num(4), "DO": seq(move(num(3)), turn(num(90)))}),
        log(text("square done")),
    ))
    return p.save("drive_square.json")


def spiral() -> dict:
    p = Program("spiral", "turtlesim", "spiral with the pen",
                "turtle1 draws a hexagonal spiral, each side a little longer, the pen changing colour.")
    p.top(seq(
        pen("255 0 0", 3),
        block("controls_for", {"VAR": p.var("i")}, {
            "FROM": num(1), "TO": num(8), "BY": num(1),
            "DO": seq(
                if_(compare("EQ", block("math_modulo", inputs={"DIVIDEND": get(p, "i"), "DIVISOR": num(2)}), number(0)),
                    pen("255 0 0", 3), else_=pen("255 220 0", 3)),
                move(arith("MULTIPLY", get(p, "i"), num(0.4))),
                turn(num(60)),
            )}),
        log(block("text_join", extraState={"itemCount": 2},
                  inputs={"ADD0": text("spiral done at x = "),
                          "ADD1": block("math_round", {"OP": "ROUND"}, {
                              "NUM": block("turtle_position", {"FIELD": "x"}, {"TURTLE": turtle()})})})),
    ))
    return p.save("spiral.json")


def three_turtles() -> dict:
    p = Program("three_turtles", "turtlesim", "spawn three turtles and move each",
                "Spawns turtle2, turtle3 and turtle4 in a row facing north, then moves each forward.")
    names = block("lists_create_with", extraState={"itemCount": 3},
                  inputs={f"ADD{i}": text(f"turtle{i + 2}") for i in range(3)})
    p.top(seq(
        set_(p, "names", names),
        set_(p, "i", number(0)),
        block("controls_forEach", {"VAR": p.var("name")}, {
            "LIST": get(p, "names"),
            "DO": seq(
                block("math_change", {"VAR": p.var("i")}, {"DELTA": num(1)}),
                block("turtle_spawn", inputs={
                    "NAME": get(p, "name"), "X": arith("MULTIPLY", get(p, "i"), num(2.5)),
                    "Y": num(2), "HEADING": num(90)}),
                pen("0 200 0", 3, who=get(p, "name")),
            )}),
        block("controls_forEach", {"VAR": p.var("name")}, {
            "LIST": get(p, "names"),
            "DO": seq(move(num(3), who=get(p, "name")), log(get(p, "name"))),
        }),
    ))
    return p.save("three_turtles.json")


# ---- rover -----------------------------------------------------------------------
def distance(direction: str) -> dict:
    return block("rover_distance", {"DIR": direction})


def velocity(speed, turn_) -> dict:
    return block("rover_set_velocity", inputs={"SPEED": speed, "TURN": turn_})


def wall_follower() -> dict:
    p = Program("wall_follower", "rover", "rover wall-follower",
                "The rover keeps a wall on its right at about 0.6 m, using /scan; it turns left at corners.")
    p.top(seq(
        log(text("following the wall on the right")),
        block("controls_whileUntil", {"MODE": "WHILE"}, {
            "BOOL": compare("LT", block("ros_elapsed"), number(120)),
            "DO": seq(
                set_(p, "ahead", distance("0")),
                set_(p, "right", distance("-90")),
                if_(compare("LT", get(p, "ahead"), number(0.7)),
                    velocity(num(0), num(60)),
                    (compare("LT", get(p, "right"), number(0.45)), velocity(num(0.3), num(25))),
                    (compare("GT", get(p, "right"), number(0.8)), velocity(num(0.3), num(-25))),
                    else_=velocity(num(0.35), num(0))),
                block("ros_sleep", inputs={"SECONDS": num(0.1)}),
            )}),
        block("rover_stop"),
    ))
    return p.save("wall_follower.json")


def pid_goal() -> dict:
    p = Program("pid_goal", "rover", "rover PID go-to-goal",
                "Drives the rover to (goal x, goal y) in odometry coordinates (it starts at 0, 0 facing x): "
                "a PID on the heading error steers, a P on the distance sets the speed.")
    gx, gy = 4.0, 2.5

    def v(name):
        return get(p, name)

    heading_to_goal = block("math_atan2", inputs={"X": v("dx"), "Y": v("dy")})  # degrees
    wrap = arith("MINUS", block("math_modulo", inputs={
        "DIVIDEND": arith("ADD", arith("MINUS", heading_to_goal, block("rover_heading")), num(540)),
        "DIVISOR": num(360)}), num(180))
    clamp = lambda value, lo, hi: block("math_constrain", inputs={"VALUE": value, "LOW": num(lo), "HIGH": num(hi)})
    loop_body = seq(
        set_(p, "dx", arith("MINUS", v("goal x"), block("rover_position", {"FIELD": "pose.pose.position.x"}))),
        set_(p, "dy", arith("MINUS", v("goal y"), block("rover_position", {"FIELD": "pose.pose.position.y"}))),
        set_(p, "distance", block("math_single", {"OP": "ROOT"}, {"NUM": arith(
            "ADD", arith("MULTIPLY", v("dx"), v("dx")), arith("MULTIPLY", v("dy"), v("dy")))})),
        set_(p, "error", wrap),
        set_(p, "integral", clamp(arith("ADD", v("integral"), arith("MULTIPLY", v("error"), num(0.1))), -30, 30)),
        set_(p, "derivative", arith("DIVIDE", arith("MINUS", v("error"), v("last error")), num(0.1))),
        set_(p, "last error", v("error")),
        set_(p, "turn", clamp(arith("ADD", arith("ADD",
                                                 arith("MULTIPLY", v("Kp"), v("error")),
                                                 arith("MULTIPLY", v("Ki"), v("integral"))),
                                     arith("MULTIPLY", v("Kd"), v("derivative"))), -90, 90)),
        set_(p, "speed", clamp(arith("MULTIPLY", num(0.6), v("distance")), 0, 0.4)),
        if_(compare("GT", block("math_single", {"OP": "ABS"}, {"NUM": v("error")}), number(40)),
            set_(p, "speed", number(0))),
        velocity(v("speed"), v("turn")),
        block("ros_sleep", inputs={"SECONDS": num(0.1)}),
    )
    p.top(seq(
        set_(p, "goal x", number(gx)), set_(p, "goal y", number(gy)),
        set_(p, "Kp", number(2.0)), set_(p, "Ki", number(0.1)), set_(p, "Kd", number(0.1)),
        set_(p, "integral", number(0)), set_(p, "last error", number(0)), set_(p, "distance", number(99)),
        block("controls_whileUntil", {"MODE": "WHILE"}, {
            "BOOL": compare("GT", v("distance"), number(0.1)), "DO": loop_body}),
        block("rover_stop"),
        log(block("text_join", extraState={"itemCount": 2}, inputs={
            "ADD0": text("arrived, distance left (cm): "),
            "ADD1": block("math_round", {"OP": "ROUND"}, {"NUM": arith("MULTIPLY", v("distance"), num(100))})})),
    ))
    return p.save("pid_goal.json")


# ---- demo action -------------------------------------------------------------------
def fibonacci() -> dict:
    p = Program("fibonacci", "any", "Fibonacci action with feedback",
                "Sends a goal to /fibonacci, logs every feedback and then the result.")
    goal = block("ros_message", {"TYPE": "example_interfaces/action/Fibonacci"},
                 {"F_order": num(8)},
                 extraState={"kind": "goal", "type": "example_interfaces/action/Fibonacci",
                             "fields": [{"name": "order", "type": "int32", "array": -1}]})
    field = lambda f, var: block("ros_field", {"FIELD": f}, {"OBJ": get(p, var)})
    p.top(seq(
        log(text("asking /fibonacci for order 8")),
        block("ros_send_goal", {
            "ACTION": "/fibonacci", "TYPE": "example_interfaces/action/Fibonacci",
            "FEEDBACK_VAR": p.var("feedback"), "RESULT_VAR": p.var("result")},
            {"GOAL": goal,
             "FEEDBACK": log(field("sequence", "feedback")),
             "RESULT": seq(log(text("result:")), log(field("sequence", "result")))}),
    ))
    return p.save("fibonacci.json")


def main() -> None:
    examples = [drive_square(), spiral(), three_turtles(), wall_follower(), pid_goal(), fibonacci()]
    (HERE / "index.json").write_text(json.dumps({"examples": examples}, indent=1) + "\n")
    print("wrote", ", ".join(e["file"] for e in examples), "and index.json")


if __name__ == "__main__":
    main()
