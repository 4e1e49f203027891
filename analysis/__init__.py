"""minimaxplan.analysis: orchestration, reports and plots (nothing imports it).

The closed loop of the paper's Figure 1 (`closed_loop.run_episode`), Monte-Carlo
experiments (`experiment.run_experiment`, Table 3), the suboptimality study
(`suboptimality`, Figure 6), model files and reports (`model_file`, `reports`), and
the ``minimaxplan`` console script (`cli`). The only layer that prints or plots.
"""
