"""Who someone is: sign-in, identity, the LMS as an identity provider.

Rooms: tokens and roles from the tokens file, rosauth MACs and the brake on guessing (``tokens``);
sign-in sessions kept in the store and the cookies' secret (``sessions``); who an LMS launch says
someone is and whether to believe it, the tool's platforms and keys (``lti``); a launch's
single-use values and the platforms' public keys fetched (``launch``); LTI Dynamic Registration,
the platforms registered from one URL (``lti_dynamic``); the courses' members as the LMS last
listed them, and whether someone left (``courses``: read from the LMS by ``lab.roster``); a share
link's signature, who shared a program (``signing``). HTTP for all of them is in ``web/``.

What someone may do is the rules' (``rules.access`` reads an ``Identity`` from here); what a class
does with the LMS (grades, the roster, a launch's landing) is the lab's.

May import: ``store`` and ``settings`` only; never ``rules``, ``lab`` or anything above them
(the rules, the lab, the bridge, runs, media, twin and web all import this room).
"""
