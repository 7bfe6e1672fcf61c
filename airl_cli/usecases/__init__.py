"""What airl does, as calls on typed settings and arrays: build a problem and its demonstrations
(``problem``), fit a reward with any registered method (``fit``), score it (``evaluate``), plan a
multi-model MDP (``plan``), and know a fit's memory before it starts (``memory``). Between the jobs
and ``core``: no Hydra, no console; a bad setting is one sentence (``ConfigError``)."""
