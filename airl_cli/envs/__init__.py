"""Problems from other packages' tabular environments.

``named`` adapts the environments airl knows by name (gymnasium's toy-text FrozenLake, CliffWalking
and Taxi, seals' CliffWorld), ``generic`` any tabular environment, by its gymnasium id or as an object.
"""
