"""The evaluation protocol: training units, cross-campaign scores, candidates and the champion.

Which campaigns a candidate is trained on (each campaign, each left-out season, all), how every
held-out campaign is scored, which candidates exist (model x selection, the physical twin, no
compensation) and which one is champion on the selection protocol; and how the champion
predicts a user's table exactly as in training.
"""
