"""Which reconstruction hypotheses are admissible (jointid.reconstruction.ranking.admissible): within
delta QAICc of the best, or in the smallest set that holds 95 % of the Akaike weight."""

import numpy as np

from jointid.reconstruction.ranking import admissible


def test_within_delta_or_in_the_95_percent_confidence_set():
    # two close hypotheses far from the rest: at delta 4.5 the second holds 1/(1+exp(2.25)) = 9.5 % of the weight
    assert admissible([0.0, 4.5, 100.0]).tolist() == [True, True, False]
    # at delta 7.2 it holds exp(-3.6)/(1+exp(-3.6)) = 2.7 %: the first alone holds 97.3 %
    assert admissible([0.0, 7.2]).tolist() == [True, False]
    # the paper's ranking today (rounded): the four within delta 4 hold 99.9 %; the fifth is out either way
    assert admissible([0.0, 0.0, 0.34, 3.59, 8.33, 12.7]).tolist() == [True] * 4 + [False] * 2
    # three equal and a fourth at 5: each of the three holds 1/(3+exp(-2.5)) = 32.4 %, together 97.3 %
    assert admissible([5.0, 0.0, 0.0, 0.0]).tolist() == [False, True, True, True]
    # order does not matter, only the values
    assert admissible([100.0, 4.5, 0.0]).tolist() == [False, True, True]


def test_along_an_axis_of_draws():
    q = np.array([[0.0, 4.5, 100.0], [7.2, 0.0, 50.0]])  # two draws, three hypotheses
    assert admissible(q).tolist() == [[True, True, False], [False, True, False]]
    assert admissible(q.T, axis=0).tolist() == [[True, False], [True, True], [False, False]]
