"""What a finished sweep reads as: the report, the claims of chapter 7, each experiment's summary and figures.

``report`` writes ``airl report``'s claims table, ``results.md`` and figures; ``claims`` holds the rule
that turns a results table into a verdict; ``summaries`` has one registered module per experiment
kind (its table, its report section); ``plotting`` draws the figures; ``transfer`` and ``variants``
read the transfer and degeneracy experiments' tables; ``alpha_values`` is the value of two models'
alpha-vectors and its upper envelope (Figs. 2-3), in numpy alone, for the sweep's rows and the figure.
"""
