"""Planning a campaign: the paper's designs, candidate designs and their predicted precision."""
