# roe sweep: the shipped run configs configs/*.json compiled into roe_app, so a sweep spec names them
# ("paper", "default") wherever roe runs; and, for roe sweep aggregate --plot, scripts/plot_sweep.py
# (cmake/embed.cmake).
roe_embed_files(roe_app embedded_run_configs ${CMAKE_SOURCE_DIR}/configs/*.json)
roe_embed_file(roe_app embedded_plot_sweep_script ${CMAKE_SOURCE_DIR}/scripts/plot_sweep.py)
