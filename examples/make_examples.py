"""Writes the example programs (Blockly workspaces in rosgate-program files) and index.json.

    python3 examples/make_examples.py

The programs are built here from small helpers so they stay readable and consistent;
the JSON files are what the IDE's Examples menu loads. Each example's title, about and block
comments are written in English on the blocks and in the IDE's other languages under
``translations`` ({lang: {name, about, comments: {block id: text}}}; index.json: ``titles``,
``abouts``): the IDE shows the reader's (js/ide/main.js), and the generated code carries the comments.
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


LANGS = ("es", "de", "fr", "pt")   # the IDE's languages besides English (ide/i18n/languages.json)


class Program:
    def __init__(self, name: str, robot: str, title: str, about: str, translations: dict[str, tuple[str, str]]):
        """translations: {lang: (title, about)} in every one of LANGS."""
        assert set(translations) == set(LANGS), f"{name}: translations in {LANGS}"
        self.name, self.robot, self.title, self.about = name, robot, title, about
        self.translations = {lang: {"name": t, "about": a, "comments": {}} for lang, (t, a) in translations.items()}
        self.variables: dict[str, str] = {}
        self.tops: list[dict] = []
        self.notes = 0

    def comment(self, b: dict, text: str, **others: str) -> dict:
        """A comment on block b in English, with its words in each of LANGS (es=..., de=...)."""
        assert set(others) == set(LANGS), f"{self.name}: a comment in {LANGS}"
        self.notes += 1
        b["id"] = f"note-{self.notes}"
        b["icons"] = {"comment": {"text": text, "pinned": False, "height": 90, "width": 260}}
        for lang, words in others.items():
            self.translations[lang]["comments"][b["id"]] = words
        return b

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
            "translations": self.translations,
            "blocks": [],
            "workspace": {
                "blocks": {"languageVersion": 0, "blocks": self.tops},
                "variables": [{"name": n, "id": i} for n, i in self.variables.items()],
            },
        }
        (HERE / file).write_text(json.dumps(doc, indent=1) + "\n")
        return {"file": file, "title": self.title, "robot": self.robot, "about": self.about,
                "titles": {lang: t["name"] for lang, t in self.translations.items()},
                "abouts": {lang: t["about"] for lang, t in self.translations.items()}}


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
                "turtle1 draws a square of side 3 and ends where it started.", {
                    "es": ("dibujar un cuadrado", "turtle1 dibuja un cuadrado de lado 3 y termina donde empezó."),
                    "de": ("ein Quadrat fahren", "turtle1 zeichnet ein Quadrat mit der Seitenlänge 3 und endet, wo es "
                                                 "begonnen hat."),
                    "fr": ("tracer un carré", "turtle1 trace un carré de côté 3 et finit là où il a commencé."),
                    "pt": ("desenhar um quadrado", "turtle1 desenha um quadrado de lado 3 e acaba onde começou.")})
    p.top(seq(
        pen("255 220 0", 4),
        p.comment(block("controls_repeat_ext", inputs={"TIMES": num(4), "DO": seq(move(num(3)), turn(num(90)))}),
                  "Four times: a side of 3, then a quarter turn (90°) to the left.",
                  es="Cuatro veces: un lado de 3 y luego un cuarto de vuelta (90°) a la izquierda.",
                  de="Viermal: eine Seite von 3, dann eine Vierteldrehung (90°) nach links.",
                  fr="Quatre fois : un côté de 3, puis un quart de tour (90°) à gauche.",
                  pt="Quatro vezes: um lado de 3 e depois um quarto de volta (90°) para a esquerda."),
        log(text("square done")),
    ))
    return p.save("drive_square.json")


def spiral() -> dict:
    p = Program("spiral", "turtlesim", "spiral with the pen",
                "turtle1 draws a hexagonal spiral, each side a little longer, the pen changing colour.", {
                    "es": ("espiral con el lápiz", "turtle1 dibuja una espiral hexagonal, cada lado un poco más largo, "
                                                   "y el lápiz cambia de color."),
                    "de": ("Spirale mit dem Stift", "turtle1 zeichnet eine sechseckige Spirale, jede Seite etwas länger, "
                                                    "der Stift wechselt die Farbe."),
                    "fr": ("spirale au crayon", "turtle1 trace une spirale hexagonale, chaque côté un peu plus long, le "
                                                "crayon changeant de couleur."),
                    "pt": ("espiral com a caneta", "turtle1 desenha uma espiral hexagonal, cada lado um pouco mais comprido, "
                                                   "e a caneta muda de cor.")})
    p.top(seq(
        pen("255 0 0", 3),
        p.comment(block("controls_for", {"VAR": p.var("i")}, {
            "FROM": num(1), "TO": num(8), "BY": num(1),
            "DO": seq(
                p.comment(
                    if_(compare("EQ", block("math_modulo", inputs={"DIVIDEND": get(p, "i"), "DIVISOR": num(2)}), number(0)),
                        pen("255 0 0", 3), else_=pen("255 220 0", 3)),
                    "Even sides red, odd sides yellow.",
                    es="Lados pares en rojo, impares en amarillo.", de="Gerade Seiten rot, ungerade gelb.",
                    fr="Côtés pairs en rouge, impairs en jaune.", pt="Lados pares a vermelho, ímpares a amarelo."),
                move(arith("MULTIPLY", get(p, "i"), num(0.4))),
                turn(num(60)),
            )}),
            "i counts the sides: side i is i × 0.4 long, so the spiral grows; 60° makes it hexagonal.",
            es="i cuenta los lados: el lado i mide i × 0,4, así la espiral crece; 60° la hace hexagonal.",
            de="i zählt die Seiten: Seite i ist i × 0,4 lang, so wächst die Spirale; 60° macht sie sechseckig.",
            fr="i compte les côtés : le côté i mesure i × 0,4, la spirale grandit ; 60° la rend hexagonale.",
            pt="i conta os lados: o lado i mede i × 0,4, por isso a espiral cresce; 60° torna-a hexagonal."),
        log(block("text_join", extraState={"itemCount": 2},
                  inputs={"ADD0": text("spiral done at x = "),
                          "ADD1": block("math_round", {"OP": "ROUND"}, {
                              "NUM": block("turtle_position", {"FIELD": "x"}, {"TURTLE": turtle()})})})),
    ))
    return p.save("spiral.json")


def three_turtles() -> dict:
    p = Program("three_turtles", "turtlesim", "spawn three turtles and move each",
                "Spawns turtle2, turtle3 and turtle4 in a row facing north, then moves each forward.", {
                    "es": ("crear tres tortugas y mover cada una", "Crea turtle2, turtle3 y turtle4 en fila mirando al "
                                                                   "norte y luego mueve cada una hacia delante."),
                    "de": ("drei Schildkröten erzeugen und jede bewegen", "Erzeugt turtle2, turtle3 und turtle4 in einer "
                           "Reihe mit Blick nach Norden und bewegt dann jede vorwärts."),
                    "fr": ("créer trois tortues et déplacer chacune", "Crée turtle2, turtle3 et turtle4 en rang, tournées "
                                                                      "vers le nord, puis avance chacune."),
                    "pt": ("criar três tartarugas e mover cada uma", "Cria turtle2, turtle3 e turtle4 em fila viradas a "
                                                                     "norte e depois move cada uma para a frente.")})
    names = block("lists_create_with", extraState={"itemCount": 3},
                  inputs={f"ADD{i}": text(f"turtle{i + 2}") for i in range(3)})
    p.top(seq(
        set_(p, "names", names),
        set_(p, "i", number(0)),
        p.comment(block("controls_forEach", {"VAR": p.var("name")}, {
            "LIST": get(p, "names"),
            "DO": seq(
                block("math_change", {"VAR": p.var("i")}, {"DELTA": num(1)}),
                block("turtle_spawn", inputs={
                    "NAME": get(p, "name"), "X": arith("MULTIPLY", get(p, "i"), num(2.5)),
                    "Y": num(2), "HEADING": num(90)}),
                pen("0 200 0", 3, who=get(p, "name")),
            )}),
            "Each turtle 2.5 further right, facing north (90°), with a green pen.",
            es="Cada tortuga 2,5 más a la derecha, mirando al norte (90°), con lápiz verde.",
            de="Jede Schildkröte 2,5 weiter rechts, Blick nach Norden (90°), mit grünem Stift.",
            fr="Chaque tortue 2,5 plus à droite, tournée vers le nord (90°), avec un crayon vert.",
            pt="Cada tartaruga 2,5 mais à direita, virada a norte (90°), com caneta verde."),
        p.comment(block("controls_forEach", {"VAR": p.var("name")}, {
            "LIST": get(p, "names"),
            "DO": seq(move(num(3), who=get(p, "name")), log(get(p, "name"))),
        }),
            "Then each of them moves 3 forward, one after the other.",
            es="Después cada una avanza 3, una tras otra.", de="Dann fährt jede 3 vorwärts, eine nach der anderen.",
            fr="Puis chacune avance de 3, l'une après l'autre.", pt="Depois cada uma avança 3, uma após a outra."),
    ))
    return p.save("three_turtles.json")


# ---- rover -----------------------------------------------------------------------
def distance(direction: str) -> dict:
    return block("rover_distance", {"DIR": direction})


def velocity(speed, turn_) -> dict:
    return block("rover_set_velocity", inputs={"SPEED": speed, "TURN": turn_})


def wall_follower() -> dict:
    p = Program("wall_follower", "rover", "rover wall-follower",
                "The rover keeps a wall on its right at about 0.6 m, using /scan; it turns left at corners.", {
                    "es": ("rover que sigue la pared", "El rover mantiene una pared a su derecha a unos 0,6 m con /scan; "
                                                       "en las esquinas gira a la izquierda."),
                    "de": ("Rover folgt der Wand", "Der Rover hält mit /scan eine Wand etwa 0,6 m rechts von sich; an "
                                                   "Ecken biegt er links ab."),
                    "fr": ("rover qui longe le mur", "Le rover garde un mur à sa droite à environ 0,6 m grâce à /scan ; "
                                                     "aux coins il tourne à gauche."),
                    "pt": ("rover que segue a parede", "O rover mantém uma parede à direita a cerca de 0,6 m com /scan; "
                                                       "nos cantos vira à esquerda.")})
    p.top(seq(
        log(text("following the wall on the right")),
        p.comment(block("controls_whileUntil", {"MODE": "WHILE"}, {
            "BOOL": compare("LT", block("ros_elapsed"), number(120)),
            "DO": seq(
                set_(p, "ahead", distance("0")),
                set_(p, "right", distance("-90")),
                p.comment(
                    if_(compare("LT", get(p, "ahead"), number(0.7)),
                        velocity(num(0), num(60)),
                        (compare("LT", get(p, "right"), number(0.45)), velocity(num(0.3), num(25))),
                        (compare("GT", get(p, "right"), number(0.8)), velocity(num(0.3), num(-25))),
                        else_=velocity(num(0.35), num(0))),
                    "A wall ahead: turn left on the spot. Too near the right wall: bear left; too far: bear right; "
                    "else straight on.",
                    es="Pared delante: girar a la izquierda sin avanzar. Muy cerca de la pared derecha: a la "
                       "izquierda; muy lejos: a la derecha; si no, recto.",
                    de="Wand voraus: auf der Stelle links drehen. Zu nah an der rechten Wand: nach links; zu weit: "
                       "nach rechts; sonst geradeaus.",
                    fr="Un mur devant : tourner à gauche sur place. Trop près du mur de droite : vers la gauche ; trop "
                       "loin : vers la droite ; sinon tout droit.",
                    pt="Parede à frente: rodar à esquerda no lugar. Demasiado perto da parede direita: para a "
                       "esquerda; demasiado longe: para a direita; senão em frente."),
                block("ros_sleep", inputs={"SECONDS": num(0.1)}),
            )}),
            "For two minutes, ten times a second: the laser's distance ahead and to the right, then steer.",
            es="Durante dos minutos, diez veces por segundo: la distancia del láser delante y a la derecha, y "
               "luego girar.",
            de="Zwei Minuten lang, zehnmal pro Sekunde: der Abstand des Lasers nach vorn und nach rechts, dann "
               "lenken.",
            fr="Pendant deux minutes, dix fois par seconde : la distance du laser devant et à droite, puis "
               "braquer.",
            pt="Durante dois minutos, dez vezes por segundo: a distância do laser à frente e à direita, e depois "
               "virar."),
        block("rover_stop"),
    ))
    return p.save("wall_follower.json")


def pid_goal() -> dict:
    p = Program("pid_goal", "rover", "rover PID go-to-goal",
                "Drives the rover to (goal x, goal y) in odometry coordinates (it starts at 0, 0 facing x): "
                "a PID on the heading error steers, a P on the distance sets the speed.", {
                    "es": ("rover PID hacia la meta", "Lleva el rover a (meta x, meta y) en coordenadas de odometría "
                           "(empieza en 0, 0 mirando a x): un PID sobre el error de rumbo gira, un P sobre la "
                           "distancia fija la velocidad."),
                    "de": ("Rover mit PID zum Ziel", "Fährt den Rover zu (Ziel x, Ziel y) in Odometrie-Koordinaten "
                           "(Start bei 0, 0 mit Blick in x-Richtung): ein PID auf dem Kursfehler lenkt, ein P auf dem "
                           "Abstand setzt die Geschwindigkeit."),
                    "fr": ("rover PID vers le but", "Conduit le rover à (but x, but y) en coordonnées d'odométrie (départ "
                           "en 0, 0 face à x) : un PID sur l'erreur de cap braque, un P sur la distance règle la "
                           "vitesse."),
                    "pt": ("rover PID até ao objetivo", "Leva o rover a (objetivo x, objetivo y) em coordenadas de "
                           "odometria (começa em 0, 0 virado para x): um PID no erro de rumo vira, um P na distância "
                           "define a velocidade.")})
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
        p.comment(set_(p, "error", wrap),
                  "The heading error in degrees, wrapped into -180..180.",
                  es="El error de rumbo en grados, llevado al intervalo -180..180.",
                  de="Der Kursfehler in Grad, in den Bereich -180..180 gebracht.",
                  fr="L'erreur de cap en degrés, ramenée dans -180..180.",
                  pt="O erro de rumo em graus, trazido para -180..180."),
        set_(p, "integral", clamp(arith("ADD", v("integral"), arith("MULTIPLY", v("error"), num(0.1))), -30, 30)),
        set_(p, "derivative", arith("DIVIDE", arith("MINUS", v("error"), v("last error")), num(0.1))),
        set_(p, "last error", v("error")),
        p.comment(set_(p, "turn", clamp(arith("ADD", arith("ADD",
                                                           arith("MULTIPLY", v("Kp"), v("error")),
                                                           arith("MULTIPLY", v("Ki"), v("integral"))),
                                               arith("MULTIPLY", v("Kd"), v("derivative"))), -90, 90)),
                  "PID: Kp × error + Ki × integral + Kd × derivative, at most 90°/s either way.",
                  es="PID: Kp × error + Ki × integral + Kd × derivada, como mucho 90°/s en cada sentido.",
                  de="PID: Kp × Fehler + Ki × Integral + Kd × Ableitung, höchstens 90°/s in jede Richtung.",
                  fr="PID : Kp × erreur + Ki × intégrale + Kd × dérivée, au plus 90°/s dans chaque sens.",
                  pt="PID: Kp × erro + Ki × integral + Kd × derivada, no máximo 90°/s em cada sentido."),
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
        p.comment(block("controls_whileUntil", {"MODE": "WHILE"}, {
            "BOOL": compare("GT", v("distance"), number(0.1)), "DO": loop_body}),
            "Until within 10 cm of the goal, every 0.1 s.",
            es="Hasta quedar a menos de 10 cm de la meta, cada 0,1 s.",
            de="Bis auf 10 cm ans Ziel heran, alle 0,1 s.",
            fr="Jusqu'à moins de 10 cm du but, toutes les 0,1 s.",
            pt="Até ficar a menos de 10 cm do objetivo, a cada 0,1 s."),
        block("rover_stop"),
        log(block("text_join", extraState={"itemCount": 2}, inputs={
            "ADD0": text("arrived, distance left (cm): "),
            "ADD1": block("math_round", {"OP": "ROUND"}, {"NUM": arith("MULTIPLY", v("distance"), num(100))})})),
    ))
    return p.save("pid_goal.json")


# ---- demo action -------------------------------------------------------------------
def fibonacci() -> dict:
    p = Program("fibonacci", "any", "Fibonacci action with feedback",
                "Sends a goal to /fibonacci, logs every feedback and then the result.", {
                    "es": ("acción Fibonacci con realimentación", "Envía un objetivo a /fibonacci, muestra cada "
                                                                  "realimentación y luego el resultado."),
                    "de": ("Fibonacci-Aktion mit Rückmeldung", "Sendet ein Ziel an /fibonacci, protokolliert jede "
                                                               "Rückmeldung und dann das Ergebnis."),
                    "fr": ("action Fibonacci avec retour", "Envoie un objectif à /fibonacci, affiche chaque retour "
                                                           "puis le résultat."),
                    "pt": ("ação Fibonacci com feedback", "Envia um objetivo para /fibonacci, mostra cada feedback e "
                                                          "depois o resultado.")})
    goal = block("ros_message", {"TYPE": "example_interfaces/action/Fibonacci"},
                 {"F_order": num(8)},
                 extraState={"kind": "goal", "type": "example_interfaces/action/Fibonacci",
                             "fields": [{"name": "order", "type": "int32", "array": -1}]})
    field = lambda f, var: block("ros_field", {"FIELD": f}, {"OBJ": get(p, var)})
    p.top(seq(
        log(text("asking /fibonacci for order 8")),
        p.comment(block("ros_send_goal", {
            "ACTION": "/fibonacci", "TYPE": "example_interfaces/action/Fibonacci",
            "FEEDBACK_VAR": p.var("feedback"), "RESULT_VAR": p.var("result")},
            {"GOAL": goal,
             "FEEDBACK": log(field("sequence", "feedback")),
             "RESULT": seq(log(text("result:")), log(field("sequence", "result")))}),
            "Each feedback is the sequence so far; the result is the whole sequence.",
            es="Cada realimentación es la secuencia hasta ahora; el resultado es la secuencia entera.",
            de="Jede Rückmeldung ist die Folge bis jetzt; das Ergebnis ist die ganze Folge.",
            fr="Chaque retour est la suite jusqu'ici ; le résultat est la suite entière.",
            pt="Cada feedback é a sequência até agora; o resultado é a sequência inteira."),
    ))
    return p.save("fibonacci.json")


def main() -> None:
    examples = [drive_square(), spiral(), three_turtles(), wall_follower(), pid_goal(), fibonacci()]
    (HERE / "index.json").write_text(json.dumps({"examples": examples}, indent=1) + "\n")
    print("wrote", ", ".join(e["file"] for e in examples), "and index.json")


if __name__ == "__main__":
    main()
