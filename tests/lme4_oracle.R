# The lme4 side of the oracle test (tests/test_lme4_oracle.py): fits every model the report fits to one study's
# trial table and writes what lme4 finds as JSON.
#
#   Rscript tests/lme4_oracle.R TRIALS.csv OUT.json [slopes [poisson] | at PARAMS.json]
#
# TRIALS.csv: participant, scene, condition (levels none, basic, full; none the reference), total_time, n_queries.
# With "slopes": the random-slope models instead (maximal, uncorrelated, slopes by participant only, LMM ML and
# REML; with "poisson" also the Poisson GLMMs of the same three structures by Laplace), each with vcov, the
# optimum's θ and its lme4 convergence messages.
# Each fit: fixef, its SEs, variance components, logLik, isSingular. lmer runs to convergence (BOBYQA to rhoend =
# 1e-12: its default stops early where the likelihood is flat). Poisson fits are lme4's own deviance function,
# restarted from its last linear predictor until its value stops changing (glmer's PIRLS evaluates the log-
# determinant at the weights of the iteration before the last, from a fixed start, which no tolPwrss fully
# converges; see analysis/glmm.py), optimized by BOBYQA from glmer's fit, with SEs from lme4's deriv12 of it;
# "glmer" holds glmer's own fit with tolPwrss = 1e-13 and "default" glmer with its defaults, to show how far those
# are.
suppressMessages({ library(lme4); library(jsonlite) })
args <- commandArgs(trailingOnly = TRUE)
d <- read.csv(args[1], stringsAsFactors = FALSE)
d$condition <- factor(d$condition, levels = c("none", "basic", "full"))
d$participant <- factor(d$participant)
d$scene <- factor(d$scene)
d$log_time <- log(d$total_time)
# the condition's treatment dummies as numbers: an uncorrelated term is one (0 + dummy | group) per dummy
d$conditionbasic <- as.numeric(d$condition == "basic")
d$conditionfull <- as.numeric(d$condition == "full")

# VarCorr by the names analysis.lmm.components gives: group, group:column, group:cor(a,b) (sdcor), residual
varcomp <- function(m) {
  v <- as.data.frame(VarCorr(m))
  grp <- sub("\\..*$", "", v$grp)
  name <- ifelse(v$grp == "Residual", "residual",
          ifelse(!is.na(v$var2), sprintf("%s:cor(%s,%s)", grp, v$var1, v$var2),
          ifelse(v$var1 == "(Intercept)", grp, sprintf("%s:%s", grp, v$var1))))
  setNames(as.list(ifelse(is.na(v$var2), v$vcov, v$sdcor)), name)
}

describe <- function(m, reml = FALSE) {
  list(fixef = as.list(fixef(m)), se = as.list(sqrt(diag(as.matrix(vcov(m))))), varcomp = varcomp(m),
       vcov = unname(as.matrix(vcov(m))), theta = unname(getME(m, "theta")), lower = getME(m, "lower"),
       logLik = as.numeric(logLik(m)), REMLcrit = if (reml) as.numeric(REMLcrit(m)) else NULL,
       df = attr(logLik(m), "df"), nobs = nobs(m), singular = isSingular(m),
       messages = as.list(m@optinfo$conv$lme4$messages))
}

CONVERGED <- glmerControl(optimizer = "bobyqa", tolPwrss = 1e-13, optCtrl = list(rhoend = 1e-10, maxfun = 1e5))

# lmer's default BOBYQA stops at ~1e-6 on θ, which in a flat likelihood (two scenes) leaves a variance ~1% off
LMM_CONVERGED <- lmerControl(optimizer = "bobyqa", optCtrl = list(rhoend = 1e-12, maxfun = 1e5))
# The random-slope models run lme4 from several starts (θ = s times the identity; lme4's own is s = 1), the best
# kept: where the likelihood has more than one optimum (random slopes with small counts), lme4's one start can stop
# on the boundary of a worse one (a Poisson study with logLik -777.6 from s = 1 and -752.1 from every other start).
# The intercept models keep lme4's one start.
STARTS <- c(1, 0.5, 0.2, 2)
start_theta <- function(formula, s) {
  lower <- lFormula(formula, d)$reTrms$lower
  ifelse(lower == 0, s, 0)
}
best_of <- function(fits) fits[[which.max(sapply(fits, function(m) as.numeric(logLik(m))))]]
lmm <- function(formula, reml = FALSE, starts = 1) {
  fits <- lapply(starts, function(s) lmer(formula, d, REML = reml, control = LMM_CONVERGED,
                                          start = list(theta = start_theta(formula, s))))
  describe(best_of(fits), reml)
}
# glmer's deviance function, restarted from its own last linear predictor until its value stops changing: the
# Laplace (or quadrature) deviance with the inner solve converged, which glmer's one pass leaves ~1e-7–1e-6 off.
restarted_deviance <- function(formula, n_agq) {
  devfun <- glmer(formula, d, family = poisson, nAGQ = n_agq, devFunOnly = TRUE)
  rho <- environment(devfun)
  rho$tolPwrss <- 1e-13
  function(p) {
    last <- Inf
    for (i in 1:50) {
      value <- devfun(p)
      rho$lp0 <- as.numeric(rho$resp$eta)
      if (abs(value - last) < 1e-11) break
      last <- value
    }
    value
  }
}

# The fit at the optimum of that deviance (BOBYQA from glmer's best converged fit, as lme4 optimizes), its SEs from lme4's
# deriv12 there; "glmer" is glmer's own fit with tolPwrss = 1e-13, "default" glmer with its defaults.
pois <- function(formula, n_agq = 1, starts = 1) {
  m <- best_of(lapply(starts, function(s) glmer(formula, d, family = poisson, nAGQ = n_agq, control = CONVERGED,
                                                start = list(theta = start_theta(formula, s)))))
  deviance <- restarted_deviance(formula, n_agq)
  theta <- getME(m, "theta")
  k <- length(theta)
  lower <- getME(m, "lower")
  opt <- minqa::bobyqa(c(theta, fixef(m)), deviance, lower = c(lower, rep(-Inf, length(fixef(m)))),
                       control = list(rhobeg = 1e-3, rhoend = 1e-11, maxfun = 1e5))
  x <- opt$par
  h <- lme4:::deriv12(deviance, x)$Hessian
  v <- tryCatch(2 * solve(h)[-seq_len(k), -seq_len(k), drop = FALSE], error = function(e) NULL)
  se <- if (is.null(v) || any(!is.finite(diag(v))) || any(diag(v) <= 0)) NULL else
    as.list(setNames(sqrt(diag(v)), names(fixef(m))))
  # the converged optimum as a fit of its own, for VarCorr's names
  devfun <- glmer(formula, d, family = poisson, nAGQ = n_agq, devFunOnly = TRUE)
  devfun(x)
  gf <- glFormula(formula, d, family = poisson)
  at <- lme4:::mkMerMod(environment(devfun), list(par = x, fval = opt$fval, conv = 0, message = ""), gf$reTrms,
                        gf$fr)
  list(fixef = as.list(setNames(x[-seq_len(k)], names(fixef(m)))), se = se,
       vcov = if (is.null(v)) NULL else unname(v), theta = unname(x[seq_len(k)]), lower = lower,
       varcomp = varcomp(at), logLik = -opt$fval / 2, nobs = nobs(m),
       singular = any(x[seq_len(k)][lower == 0] < 1e-4),
       se_glmer = as.list(sqrt(diag(as.matrix(vcov(m))))), glmer = describe(m),
       default = describe(glmer(formula, d, family = poisson, nAGQ = n_agq)))
}

if (length(args) > 2 && args[3] %in% c("slopes", "at")) {
  maximal <- ~ (1 + condition | participant) + (1 + condition | scene)
  uncorrelated <- ~ (1 | participant) + (0 + conditionbasic | participant) + (0 + conditionfull | participant) +
    (1 | scene) + (0 + conditionbasic | scene) + (0 + conditionfull | scene)
  by_participant <- ~ (1 + condition | participant) + (1 | scene)
  text <- function(x) paste(deparse(x, width.cutoff = 500L), collapse = " ")
  with_random <- function(fixed, random) as.formula(paste(text(fixed), "+", text(random[[2]])))
  # a model of the test by its name: time_maximal, time_maximal_null, time_maximal_reml, queries_by_participant, …
  model <- function(name) {
    parts <- regmatches(name, regexec("^(time|queries)_(maximal|uncorrelated|by_participant)(_null|_reml)?$", name))[[1]]
    response <- if (parts[2] == "time") "log_time" else "n_queries"
    fixed <- as.formula(paste(response, if (parts[4] == "_null") "~ 1" else "~ condition"))
    list(formula = with_random(fixed, get(parts[3])), poisson = parts[2] == "queries", reml = parts[4] == "_reml")
  }
  if (args[3] == "at") {
    # lme4's own deviance at the parameters another fit found (PARAMS.json: per model, θ by lme4's names, β):
    # whether a log-likelihood above lme4's optimum is lme4's likelihood at a better optimum
    at <- fromJSON(args[4])
    out <- list()
    for (name in names(at)) {
      m <- model(name)
      if (m$poisson) {
        devfun <- restarted_deviance(m$formula, 1)
        names_theta <- names(getME(glmer(m$formula, d, family = poisson), "theta"))
        value <- devfun(c(unlist(at[[name]]$theta)[names_theta], unlist(at[[name]]$beta)))
      } else {
        fitted <- lmer(m$formula, d, REML = m$reml)
        devfun <- lmer(m$formula, d, REML = m$reml, devFunOnly = TRUE)
        value <- devfun(unlist(at[[name]]$theta)[names(getME(fitted, "theta"))])
      }
      out[[name]] <- -value / 2
    }
    write_json(out, args[2], digits = NA, auto_unbox = TRUE, pretty = TRUE)
    quit(save = "no")
  }
  out <- list(versions = list(R = R.version.string, lme4 = as.character(packageVersion("lme4"))))
  for (structure in c("maximal", "uncorrelated", "by_participant")) {
    for (suffix in c("", "_null", "_reml")) {
      name <- paste0("time_", structure, suffix)
      m <- model(name)
      out[[name]] <- lmm(m$formula, reml = m$reml, starts = STARTS)
    }
  }
  if (length(args) > 3 && args[4] == "poisson") {  # the Poisson GLMMs with the same structures too
    for (structure in c("maximal", "uncorrelated", "by_participant")) {
      for (suffix in c("", "_null")) {
        name <- paste0("queries_", structure, suffix)
        out[[name]] <- pois(model(name)$formula, starts = STARTS)
      }
    }
  }
  write_json(out, args[2], digits = NA, auto_unbox = TRUE, null = "null", pretty = TRUE)
  quit(save = "no")
}

out <- list(
  versions = list(R = R.version.string, lme4 = as.character(packageVersion("lme4"))),
  time_ml = lmm(total_time ~ condition + (1 | participant) + (1 | scene)),
  time_ml_null = lmm(total_time ~ 1 + (1 | participant) + (1 | scene)),
  time_reml = lmm(total_time ~ condition + (1 | participant) + (1 | scene), reml = TRUE),
  log_time_ml = lmm(log_time ~ condition + (1 | participant) + (1 | scene)),
  log_time_ml_null = lmm(log_time ~ 1 + (1 | participant) + (1 | scene)),
  queries = pois(n_queries ~ condition + (1 | participant) + (1 | scene)),
  queries_null = pois(n_queries ~ 1 + (1 | participant) + (1 | scene)),
  queries_laplace_participant = pois(n_queries ~ condition + (1 | participant)),
  queries_agq_participant = pois(n_queries ~ condition + (1 | participant), n_agq = 10)
)
write_json(out, args[2], digits = NA, auto_unbox = TRUE, null = "null", pretty = TRUE)
